//! The film: colour and AOV buffers of the rendered window.

use crate::integrator::Aov;
use crate::math::Rgb;

/// The part of the image that is rendered, in pixels of the full film.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

/// Rendered pixels of a window: linear RGB plus the integrator's AOV channels.
#[derive(Clone, Debug)]
pub struct Film {
    /// Size of the full film.
    pub full_width: u32,
    pub full_height: u32,
    pub window: Window,
    pub color: Vec<Rgb>,
    pub aovs: Vec<Aov>,
    /// Per pixel, all AOV channels consecutively (in the order of `aovs`).
    pub aov_data: Vec<f32>,
}

impl Film {
    pub fn new(full_width: u32, full_height: u32, window: Window, aovs: Vec<Aov>) -> Self {
        let n = window.width as usize * window.height as usize;
        let channels = aov_channel_count(&aovs);
        Film {
            full_width,
            full_height,
            window,
            color: vec![Rgb::ZERO; n],
            aov_data: vec![0.0; n * channels],
            aovs,
        }
    }

    /// Number of AOV floats per pixel.
    pub fn aov_channels(&self) -> usize {
        aov_channel_count(&self.aovs)
    }

    /// Values of channel `channel` of AOV `aov`, one per pixel in row order.
    pub fn aov_channel(&self, aov: usize, channel: usize) -> impl Iterator<Item = f32> + '_ {
        let offset: usize = self.aovs[..aov]
            .iter()
            .map(|a| a.channels.len())
            .sum::<usize>()
            + channel;
        let stride = self.aov_channels();
        self.aov_data
            .iter()
            .skip(offset)
            .step_by(stride.max(1))
            .copied()
    }
}

fn aov_channel_count(aovs: &[Aov]) -> usize {
    aovs.iter().map(|a| a.channels.len()).sum()
}
