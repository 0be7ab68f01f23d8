//! `lumis import`: converts a Mitsuba XML scene (Mitsuba 3, or 0.x upgraded as Mitsuba 3 reads
//! it) to a lumis RON scene.
//!
//! The subset converted is what lumis renders the same way (see docs/scene-format.md,
//! "Importing Mitsuba scenes"). Every element or property it cannot convert is reported with
//! its file and line, never dropped silently; conventions that differ without changing the
//! expected image are noted.

/// The converter, and the parts of its reading its tests check: files' versions and
/// parameters, property names, paths and spectra.
pub mod mitsuba;

pub use mitsuba::{Conversion, Problem, Version, convert, convert_file};

use anyhow::{Result, bail};
use std::path::Path;

/// `lumis import SCENE.xml -o SCENE.ron`: converts, prints notes and problems (as
/// `FILE:LINE: ...`), and writes the RON scene atomically unless something could not be
/// converted (or `partial`; a scene without a convertible sensor is never written).
pub fn run(scene: &Path, output: &Path, defines: &[String], partial: bool) -> Result<()> {
    let defines = defines
        .iter()
        .map(|d| {
            d.split_once('=')
                .map(|(n, v)| (n.trim().to_string(), v.to_string()))
                .ok_or_else(|| anyhow::anyhow!("-D `{d}` is not NAME=VALUE"))
        })
        .collect::<Result<Vec<_>>>()?;
    let out_dir = output.parent().unwrap_or(Path::new(""));
    let conversion = convert_file(scene, out_dir, &defines).map_err(|e| anyhow::anyhow!(e))?;
    for note in &conversion.notes {
        eprintln!("note: {note}");
    }
    for problem in &conversion.problems {
        eprintln!(
            "{}: {problem}",
            if partial && !conversion.camera_missing {
                "skipped"
            } else {
                "error"
            }
        );
    }
    if conversion.camera_missing {
        bail!(
            "{} has no sensor lumis can convert: nothing written, even with --partial (a \
             stand-in camera would render another image)",
            scene.display()
        );
    }
    if !conversion.problems.is_empty() && !partial {
        bail!(
            "{} element(s) of {} cannot be converted (listed above); nothing written (--partial \
             writes the rest)",
            conversion.problems.len(),
            scene.display()
        );
    }
    crate::image_io::write_atomically(output, |f| {
        use std::io::Write;
        f.write_all(conversion.ron.as_bytes())
            .map_err(|e| e.to_string())
    })?;
    eprintln!("wrote {}", output.display());
    Ok(())
}
