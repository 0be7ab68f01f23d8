//! `lumis import`: converts a Mitsuba 3 XML scene to a lumis RON scene.
//!
//! The subset converted is what lumis renders the same way (see docs/scene-format.md,
//! "Importing Mitsuba 3 scenes"): a `perspective` sensor with an `hdrfilm` and an
//! `independent` sampler, the `direct` integrator, `obj`, `ply`, `rectangle`, `cube`, `sphere`
//! and `disk` shapes, `diffuse`, `roughconductor` and `conductor` BSDFs (`twosided` or not),
//! `area`, `envmap`, `point` and `directional` emitters, `default` parameters and `$`
//! substitution. Every element or property it cannot convert is reported with its line, never
//! dropped silently; conventions that differ without changing the expected image are noted.

mod mitsuba;

pub use mitsuba::{Conversion, Problem, convert};

use anyhow::{Context, Result, bail};
use std::path::Path;

/// `lumis import SCENE.xml -o SCENE.ron`: converts, prints notes and problems (as
/// `FILE:LINE: ...`), and writes the RON scene atomically unless something could not be
/// converted (or `partial`).
pub fn run(scene: &Path, output: &Path, defines: &[String], partial: bool) -> Result<()> {
    let xml = std::fs::read_to_string(scene)
        .with_context(|| format!("cannot read {}", scene.display()))?;
    let defines = defines
        .iter()
        .map(|d| {
            d.split_once('=')
                .map(|(n, v)| (n.trim().to_string(), v.to_string()))
                .with_context(|| format!("-D `{d}` is not NAME=VALUE"))
        })
        .collect::<Result<Vec<_>>>()?;
    let xml_dir = scene.parent().unwrap_or(Path::new(""));
    let out_dir = output.parent().unwrap_or(Path::new(""));
    let conversion = convert(&xml, xml_dir, out_dir, &defines)
        .map_err(|e| anyhow::anyhow!("{}: {e}", scene.display()))?;
    for note in &conversion.notes {
        eprintln!("note: {}:{}: {}", scene.display(), note.line, note.message);
    }
    for problem in &conversion.problems {
        eprintln!(
            "{}: {}:{}: {}",
            if partial { "skipped" } else { "error" },
            scene.display(),
            problem.line,
            problem.message
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
