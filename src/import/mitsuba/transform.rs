//! `<transform>`: its operations (translate, scale, rotate, matrix, lookat) composed into one
//! matrix, and that matrix as the scene's `transform: (matrix: ...)`.

use super::Report;
use super::files::Version;
use super::properties::{Xml, line};
use glam::{DMat4, DVec3, DVec4};
use lumis_core::scene::description::TransformDescription;
use roxmltree::Node;

/// A `<transform>`'s matrix (its operations applied in order), or `None` after a problem.
/// Files older than Mitsuba 2 may write `<lookAt>` for `<lookat>` (noted).
pub(super) fn read(
    node: &Node,
    xml: &Xml,
    report: &mut Report,
    version: Version,
) -> Result<Option<DMat4>, String> {
    let mut m = DMat4::IDENTITY;
    for op in node.children().filter(Node::is_element) {
        let at = line(&op);
        let step = match op.tag_name().name() {
            "translate" => DMat4::from_translation(xml.vector(&op, 0.0)?),
            "scale" => DMat4::from_scale(xml.vector(&op, 1.0)?),
            "rotate" => {
                let axis = xml.vector(&op, 0.0)?;
                let angle = xml.required(&op, "angle")?;
                let angle = xml.numbers(&op, &angle)?.first().copied().unwrap_or(0.0);
                if axis.length_squared() == 0.0 {
                    return Err(format!("line {at}: a rotation axis must not be zero"));
                }
                let length = axis.length();
                if (length - 1.0).abs() > 1e-6 {
                    report.note(
                        at,
                        format!(
                            "the rotation axis ({}, {}, {}) is not of unit length ({length:.4}): \
                             Mitsuba 3 does not normalise it (Dr.Jit's `rotate`), so its matrix \
                             turns and also stretches; converted as Mitsuba reads it",
                            axis.x, axis.y, axis.z
                        ),
                    );
                }
                rotation(axis, angle)
            }
            "matrix" => matrix(&op, xml)?,
            "lookAt" if version.is_legacy() => {
                report.note(
                    at,
                    "<lookAt> (Mitsuba 0.x) read as <lookat> (Mitsuba 3 itself refuses it)",
                );
                match look_at(&op, xml, report)? {
                    Some(m) => m,
                    None => return Ok(None),
                }
            }
            "lookat" => match look_at(&op, xml, report)? {
                Some(m) => m,
                None => return Ok(None),
            },
            other => {
                report.problem(
                    at,
                    format!("transform operation <{other}> is not converted"),
                );
                return Ok(None);
            }
        };
        m = step * m;
    }
    Ok(Some(m))
}

/// The scene's transform for `m`: its full matrix, row-major.
pub(super) fn description(m: DMat4) -> TransformDescription {
    let rows = std::array::from_fn(|i| m.col(i % 4)[i / 4] as f32);
    TransformDescription {
        matrix: Some(rows),
        ..TransformDescription::default()
    }
}

/// `<matrix value="...">`: 16 numbers (or 9, a 3×3 linear part), row-major.
fn matrix(op: &Node, xml: &Xml) -> Result<DMat4, String> {
    let v = xml.required(op, "value")?;
    let n = xml.numbers(op, &v)?;
    match n.len() {
        16 => Ok(DMat4::from_cols_array(&n.try_into().expect("16")).transpose()),
        9 => {
            let r = |i: usize| DVec4::new(n[3 * i], n[3 * i + 1], n[3 * i + 2], 0.0);
            Ok(DMat4::from_cols(r(0), r(1), r(2), DVec4::W).transpose())
        }
        k => Err(format!(
            "line {}: a matrix has 9 or 16 numbers, not {k}",
            line(op)
        )),
    }
}

/// `<lookat origin target up>`: the frame at `origin` whose +z looks at `target`, or `None`
/// after a problem.
fn look_at(op: &Node, xml: &Xml, report: &mut Report) -> Result<Option<DMat4>, String> {
    let at = line(op);
    let read = |name: &str| -> Result<Option<DVec3>, String> {
        match xml.attribute(op, name)? {
            Some(t) => match xml.numbers(op, &t)?.as_slice() {
                [x, y, z] => Ok(Some(DVec3::new(*x, *y, *z))),
                _ => Err(format!("line {at}: `{name}` needs 3 numbers")),
            },
            None => Ok(None),
        }
    };
    let (Some(origin), Some(target)) = (read("origin")?, read("target")?) else {
        return Err(format!("line {at}: <lookat> needs `origin` and `target`"));
    };
    let Some(up) = read("up")? else {
        report.problem(at, "<lookat> without `up` is not converted");
        return Ok(None);
    };
    let dir = (target - origin).normalize_or_zero();
    let left = up.cross(dir).normalize_or_zero();
    if dir == DVec3::ZERO || left == DVec3::ZERO {
        return Err(format!(
            "line {at}: <lookat> needs distinct origin and target, and `up` not along the view"
        ));
    }
    let new_up = dir.cross(left);
    Ok(Some(DMat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        origin.extend(1.0),
    )))
}

/// Mitsuba's (Dr.Jit's) rotation matrix by `degrees` about `axis`, c I + (1 − c) a aᵀ + s [a]×,
/// which is a rotation only for a unit `axis` (Mitsuba does not normalise it), with sin and cos
/// exact at multiples of 90° (as lumis' own `rotate`, so that turned planes stay exactly
/// axis-aligned).
fn rotation(axis: DVec3, degrees: f64) -> DMat4 {
    let quarter_turns = degrees / 90.0;
    let (s, c) = if quarter_turns == quarter_turns.round() {
        [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0)]
            [(quarter_turns as i64).rem_euclid(4) as usize]
    } else {
        degrees.to_radians().sin_cos()
    };
    let t = 1.0 - c;
    let DVec3 { x, y, z } = axis;
    DMat4::from_cols(
        DVec4::new(c + t * x * x, t * x * y + s * z, t * x * z - s * y, 0.0),
        DVec4::new(t * x * y - s * z, c + t * y * y, t * y * z + s * x, 0.0),
        DVec4::new(t * x * z + s * y, t * y * z - s * x, c + t * z * z, 0.0),
        DVec4::W,
    )
}
