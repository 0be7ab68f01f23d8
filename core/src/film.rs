//! The film: colour and AOV buffers of the rendered window.

use crate::math::Rgb;
use crate::output::{Aov, Window};

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

/// One AOV layer of a film, found by name with [`Film::aov`].
#[derive(Clone, Copy, Debug)]
pub struct AovLayer<'a> {
    film: &'a Film,
    /// Offset of the layer's first channel within a pixel's AOV values.
    offset: usize,
    aov: &'a Aov,
}

impl AovLayer<'_> {
    /// The layer's channel names, in order.
    pub fn channel_names(&self) -> &[String] {
        &self.aov.channels
    }

    /// Values of the channel named `name`, one per pixel in row order; `None` if the layer has
    /// no such channel.
    pub fn channel(&self, name: &str) -> Option<Vec<f32>> {
        let index = self.aov.channels.iter().position(|c| c == name)?;
        Some(self.film.channel_values(self.offset + index).collect())
    }

    /// Every channel's values, in the order of [`channel_names`](Self::channel_names).
    pub fn channels(&self) -> Vec<Vec<f32>> {
        (0..self.aov.channels.len())
            .map(|c| self.film.channel_values(self.offset + c).collect())
            .collect()
    }
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

    /// The AOV layer named `name`, if the integrator declared it.
    pub fn aov(&self, name: &str) -> Option<AovLayer<'_>> {
        let index = self.aovs.iter().position(|a| a.name == name)?;
        Some(AovLayer {
            film: self,
            offset: aov_channel_count(&self.aovs[..index]),
            aov: &self.aovs[index],
        })
    }

    /// Values of channel `channel` of AOV `aov` (positions in `aovs` and its channels), one per
    /// pixel in row order: for writers that go through every layer; readers of a particular
    /// layer use [`aov`](Self::aov).
    pub fn aov_channel(&self, aov: usize, channel: usize) -> impl Iterator<Item = f32> + '_ {
        self.channel_values(aov_channel_count(&self.aovs[..aov]) + channel)
    }

    /// Values of the AOV channel at `offset` within a pixel's AOV values.
    fn channel_values(&self, offset: usize) -> impl Iterator<Item = f32> + '_ {
        self.aov_data
            .iter()
            .skip(offset)
            .step_by(self.aov_channels().max(1))
            .copied()
    }
}

fn aov_channel_count(aovs: &[Aov]) -> usize {
    aovs.iter().map(|a| a.channels.len()).sum()
}
