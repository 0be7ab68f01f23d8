//! Typed plugin parameters: declared once per plugin, checked when a scene is built.
//!
//! A plugin declares its parameters as a `&'static [ParamSpec]` (name, type, default, unit, meaning).
//! That list is the single source of truth: `lumis plugins` prints it, the docs are checked
//! against it, defaults come from it, and the scene builder refuses parameters it does not name,
//! values of the wrong type or out of range, and parameters a plugin was given but did not use.
//!
//! Why one file of over 600 lines: the parameter declarations, the typed reads and their checks
//! (unknown, mistyped, out of range, unused) are one interface; with its tests.

use crate::bsdf::{Bsdf, BsdfFlags};
use crate::error::did_you_mean;
use crate::limits::{MAX_COORDINATE, fmt_f32, fmt_number};
use crate::texture::Texture;
use glam::Vec3;
use ron::Value;
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::Arc;

mod nested;

/// The type of a parameter, with its default (`None`: the parameter is required) and range.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub enum ParamKind {
    Float {
        default: Option<f32>,
        min: f32,
        max: f32,
    },
    Int {
        default: Option<i64>,
        min: i64,
        max: i64,
    },
    Bool {
        default: Option<bool>,
    },
    /// Linear RGB: `(r, g, b)` or one number for grey; each channel in [0, max].
    Rgb {
        default: Option<[f32; 3]>,
        max: f32,
    },
    /// A position or direction: each component finite and within the scene's coordinate range,
    /// ±[`MAX_COORDINATE`].
    Vec3 {
        default: Option<[f32; 3]>,
    },
    /// A pair `(lo, hi)` with lo <= hi, both in [min, max].
    Interval {
        default: [f32; 2],
        min: f32,
        max: f32,
    },
    Str {
        default: Option<&'static str>,
    },
    /// A path, resolved relative to the scene file.
    Path,
    /// A list of distinct options, e.g. `["alpha", "samples"]`; empty by default.
    List {
        options: &'static [&'static str],
    },
    Choice {
        options: &'static [&'static str],
        default: &'static str,
    },
    /// A colour as [`ParamKind::Rgb`], or a texture written inline,
    /// `(type: "checkerboard", ...)`, whose values must lie in [0, max] too. Read with
    /// [`Params::rgb_or_texture`].
    RgbOrTexture {
        default: Option<[f32; 3]>,
        max: f32,
    },
    /// A number as [`ParamKind::Float`], or a texture written inline (its `eval_1`), whose
    /// values must lie in [min, max] too. Read with [`Params::float_or_texture`].
    FloatOrTexture {
        default: Option<f32>,
        min: f32,
        max: f32,
    },
    /// Another BSDF: the name of one of the scene's `bsdfs`, or one written inline,
    /// `(type: "diffuse", ...)`. Required. Read with [`Params::bsdf`].
    Bsdf,
    /// A 2D affine map of texture coordinates: `(scale: (sx, sy), rotate: degrees,
    /// translate: (tx, ty))` (each optional, applied in that order; `scale` may be one number)
    /// or `(matrix: (a, b, c, d, e, f))`, the rows of (u, v) ↦ (a u + b v + c, d u + e v + f).
    /// The identity by default. Read with [`Params::uv_transform`].
    UvTransform,
}

/// One declared parameter of a plugin.
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    pub name: &'static str,
    pub kind: ParamKind,
    /// Physical unit, or "" for dimensionless values.
    pub unit: &'static str,
    pub description: &'static str,
}

impl ParamSpec {
    /// The type as written in docs: `float`, `rgb`, ...
    pub fn type_name(&self) -> &'static str {
        match self.kind {
            ParamKind::Float { .. } => "float",
            ParamKind::Int { .. } => "integer",
            ParamKind::Bool { .. } => "bool",
            ParamKind::Rgb { .. } => "rgb",
            ParamKind::Vec3 { .. } => "vector",
            ParamKind::Interval { .. } => "interval",
            ParamKind::Str { .. } => "string",
            ParamKind::Path => "path",
            ParamKind::List { .. } => "list",
            ParamKind::Choice { .. } => "choice",
            ParamKind::RgbOrTexture { .. } => "rgb or texture",
            ParamKind::FloatOrTexture { .. } => "float or texture",
            ParamKind::Bsdf => "bsdf",
            ParamKind::UvTransform => "uv transform",
        }
    }

    /// The default as RON text, or "required".
    pub fn default_text(&self) -> String {
        let triple = |v: [f32; 3]| format!("({}, {}, {})", v[0], v[1], v[2]);
        match self.kind {
            ParamKind::Float {
                default: Some(v), ..
            }
            | ParamKind::FloatOrTexture {
                default: Some(v), ..
            } => format!("{v}"),
            ParamKind::Int {
                default: Some(v), ..
            } => format!("{v}"),
            ParamKind::Bool { default: Some(v) } => format!("{v}"),
            ParamKind::Rgb {
                default: Some(v), ..
            }
            | ParamKind::RgbOrTexture {
                default: Some(v), ..
            }
            | ParamKind::Vec3 { default: Some(v) } => triple(v),
            ParamKind::UvTransform => "identity".to_string(),
            ParamKind::Interval { default, .. } => format!("({}, {})", default[0], default[1]),
            ParamKind::Str { default: Some(v) } => format!("{v:?}"),
            ParamKind::Choice { default, .. } => format!("{default:?}"),
            ParamKind::List { .. } => "[]".to_string(),
            _ => "required".to_string(),
        }
    }

    /// Valid values, for docs: a range or the list of choices.
    pub fn range_text(&self) -> String {
        let number = fmt_f32;
        match self.kind {
            ParamKind::Float { min, max, .. }
            | ParamKind::FloatOrTexture { min, max, .. }
            | ParamKind::Interval { min, max, .. } => {
                let hi = if max.is_infinite() {
                    "∞)".to_string()
                } else {
                    format!("{}]", number(max))
                };
                format!("[{}, {hi}", number(min))
            }
            ParamKind::Int { min, max, .. } => format!("[{min}, {max}]"),
            ParamKind::Rgb { max, .. } | ParamKind::RgbOrTexture { max, .. } if max.is_finite() => {
                format!("[0, {}] per channel", number(max))
            }
            ParamKind::Rgb { .. } | ParamKind::RgbOrTexture { .. } => {
                "finite, non-negative per channel".into()
            }
            ParamKind::Vec3 { .. } => format!("[-{0}, {0}] per component", number(MAX_COORDINATE)),
            ParamKind::Choice { options, .. } => options.join(" | "),
            ParamKind::List { options } => format!("any of {}", options.join(", ")),
            _ => String::new(),
        }
    }
}

/// What went wrong with a plugin's parameters or construction.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PluginError {
    #[error("unknown parameter `{name}`{suggestion}; {plugin} takes: {valid}")]
    Unknown {
        plugin: String,
        name: String,
        suggestion: String,
        valid: String,
    },
    #[error("parameter `{name}` is not used by {plugin}: {why}")]
    Unused {
        plugin: String,
        name: String,
        why: String,
    },
    #[error("parameter `{name}` of {plugin} expects {expected}, found {found}")]
    WrongType {
        plugin: String,
        name: String,
        expected: String,
        found: String,
    },
    #[error("parameter `{name}` of {plugin} is required ({expected})")]
    Missing {
        plugin: String,
        name: String,
        expected: String,
    },
    #[error("parameter `{name}` of {plugin} must be in {range}, found {found}")]
    OutOfRange {
        plugin: String,
        name: String,
        range: String,
        found: String,
    },
    #[error("{0}")]
    Invalid(String),
}

/// The parameters given to one plugin instance, with use tracking.
pub struct Params {
    plugin: String,
    specs: &'static [ParamSpec],
    values: BTreeMap<String, Value>,
    used: Vec<String>,
    /// Directory that relative paths are resolved against (the scene file's).
    base_dir: PathBuf,
    /// Builds the textures and BSDFs the parameters name ([`References`]); none: a parameter
    /// that names one is refused.
    references: Option<Rc<dyn References>>,
    /// Whether a texture was handed out (here or to a nested BSDF): the plugin varies over the
    /// surface.
    textured: bool,
}

/// What builds the plugins that parameters refer to: textures written inline, and BSDFs
/// written inline or named from the scene's `bsdfs` (the scene loader's
/// `scene::references::SceneReferences`). Errors are sentences naming the problem; the reader
/// adds the parameter and its plugin.
pub trait References {
    /// The texture written inline as `value` (a plugin description), for the parameter
    /// described by `label`.
    fn texture(self: Rc<Self>, label: &str, value: &Value) -> Result<Arc<dyn Texture>, String>;
    /// The BSDF `value` names (a string) or describes inline, for the parameter described by
    /// `label`, with its flags ([`BsdfFlags::SPATIALLY_VARYING`] where it was given a texture).
    fn bsdf(
        self: Rc<Self>,
        label: &str,
        value: &Value,
    ) -> Result<(Arc<dyn Bsdf>, BsdfFlags), String>;
}

/// A short description of a RON value, for "found ..." messages.
pub fn describe_value(v: &Value) -> String {
    match v {
        Value::Bool(b) => format!("the bool {b}"),
        Value::Char(c) => format!("the char {c:?}"),
        Value::Map(_) => "a map or struct".into(),
        Value::Number(n) => format!("the number {}", n.into_f64()),
        Value::Option(None) => "None".into(),
        Value::Option(Some(inner)) => format!("Some({})", describe_value(inner)),
        Value::String(s) => format!("the string {s:?}"),
        Value::Bytes(_) => "bytes".into(),
        Value::Seq(s) => format!("a tuple or list of {} elements", s.len()),
        Value::Unit => "()".into(),
    }
}

/// A number as written (f64, so that a value beyond f32's range is reported as given).
fn as_number(v: &Value) -> Option<f64> {
    match v {
        Value::Number(n) => Some(n.into_f64()),
        _ => None,
    }
}

fn as_triple(v: &Value) -> Option<[f64; 3]> {
    match v {
        Value::Seq(s) if s.len() == 3 => {
            let mut out = [0.0; 3];
            for (o, x) in out.iter_mut().zip(s) {
                *o = as_number(x)?;
            }
            Some(out)
        }
        _ => None,
    }
}

/// Whether `v`, as written (f64), is in [min, max] once it is an f32: `1e12` is accepted for a
/// maximum of 1e12 (which rounds to 999 999 995 904 in f32), and `1e39` refused (not as an f32
/// infinity). False for NaN.
fn in_range(v: f64, min: f32, max: f32) -> bool {
    let x = v as f32;
    x.is_finite() && x >= min && x <= max
}

/// "(1, NaN, 3)", each number as [`fmt_number`] writes it.
fn fmt_numbers(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|&v| fmt_number(v)).collect();
    format!("({})", items.join(", "))
}

impl Params {
    /// Checks every given name against the plugin's declared parameters.
    /// `plugin` names the instance for messages, e.g. "bsdf `red` (diffuse)".
    pub fn new(
        plugin: impl Into<String>,
        specs: &'static [ParamSpec],
        values: BTreeMap<String, Value>,
    ) -> Result<Self, PluginError> {
        let plugin = plugin.into();
        for name in values.keys() {
            if !specs.iter().any(|s| s.name == name) {
                let valid = if specs.is_empty() {
                    "no parameters".to_string()
                } else {
                    specs
                        .iter()
                        .map(|s| format!("`{}`", s.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                return Err(PluginError::Unknown {
                    plugin,
                    name: name.clone(),
                    suggestion: did_you_mean(name, specs.iter().map(|s| s.name)),
                    valid,
                });
            }
        }
        Ok(Params {
            plugin,
            specs,
            values,
            used: Vec::new(),
            base_dir: PathBuf::new(),
            references: None,
            textured: false,
        })
    }

    /// Builds the textures and BSDFs the parameters refer to with `references`.
    pub fn with_references(mut self, references: Rc<dyn References>) -> Self {
        self.references = Some(references);
        self
    }

    /// The directory relative paths are resolved against.
    pub fn base_dir(&self) -> &Path {
        &self.base_dir
    }

    /// Whether a texture was handed out to the plugin, or to a BSDF nested in it: the plugin
    /// varies over the surface.
    pub fn uses_textures(&self) -> bool {
        self.textured
    }

    /// Resolves relative `path` parameters against `dir` (the scene file's directory).
    pub fn with_base_dir(mut self, dir: &Path) -> Self {
        self.base_dir = dir.to_path_buf();
        self
    }

    /// The instance description used in messages.
    pub fn plugin(&self) -> &str {
        &self.plugin
    }

    /// Whether the scene gave this parameter explicitly.
    pub fn is_given(&self, name: &str) -> bool {
        self.values.contains_key(name)
    }

    fn spec(&self, name: &str) -> &'static ParamSpec {
        self.specs
            .iter()
            .find(|s| s.name == name)
            .unwrap_or_else(|| {
                panic!(
                    "{} reads parameter `{name}` it does not declare",
                    self.plugin
                )
            })
    }

    /// The declaration and the given value (cloned: values are a few numbers), marking it used.
    fn take(&mut self, name: &str) -> (&'static ParamSpec, Option<Value>) {
        let spec = self.spec(name);
        if !self.used.iter().any(|u| u == name) {
            self.used.push(name.to_string());
        }
        (spec, self.values.get(name).cloned())
    }

    fn wrong_type(&self, name: &str, expected: &str, found: &Value) -> PluginError {
        PluginError::WrongType {
            plugin: self.plugin.clone(),
            name: name.to_string(),
            expected: expected.to_string(),
            found: describe_value(found),
        }
    }

    fn missing(&self, spec: &ParamSpec, expected: &str) -> PluginError {
        PluginError::Missing {
            plugin: self.plugin.clone(),
            name: spec.name.to_string(),
            expected: expected.to_string(),
        }
    }

    fn out_of_range(&self, spec: &ParamSpec, found: String) -> PluginError {
        PluginError::OutOfRange {
            plugin: self.plugin.clone(),
            name: spec.name.to_string(),
            range: spec.range_text(),
            found,
        }
    }

    /// A value not a finite number, or outside the declared range, named with its parameter.
    fn bad_number(&self, spec: &ParamSpec, values: &[f64]) -> PluginError {
        let found = if values.len() == 1 {
            fmt_number(values[0])
        } else {
            fmt_numbers(values)
        };
        if values.iter().all(|v| v.is_finite()) {
            return self.out_of_range(spec, found);
        }
        PluginError::Invalid(format!(
            "parameter `{}` of {} must be finite ({}), found {found}",
            spec.name,
            self.plugin,
            spec.range_text()
        ))
    }

    pub fn float(&mut self, name: &str) -> Result<f32, PluginError> {
        let (spec, value) = self.take(name);
        let ParamKind::Float { default, min, max } = spec.kind else {
            panic!("parameter `{name}` is not declared as a float");
        };
        self.float_value(spec, value.as_ref(), default, [min, max], "a number")
    }

    /// A parameter declared as a [`ParamKind::Float`] that may also be given as one of
    /// `names` (compared without regard to case, as Mitsuba compares its material names): the
    /// number it names, or the number given, in the declared range. A name not among them is
    /// an error that lists them and the closest.
    pub fn float_or_name(
        &mut self,
        name: &str,
        names: &[(&'static str, f32)],
    ) -> Result<f32, PluginError> {
        let (spec, value) = self.take(name);
        let ParamKind::Float { default, min, max } = spec.kind else {
            panic!("parameter `{name}` is not declared as a float");
        };
        if let Some(Value::String(given)) = &value {
            let lower = given.to_lowercase();
            return names
                .iter()
                .find(|(n, _)| *n == lower)
                .map(|&(_, v)| v)
                .ok_or_else(|| PluginError::OutOfRange {
                    plugin: self.plugin.clone(),
                    name: name.to_string(),
                    range: format!(
                        "a number in {} or one of {}",
                        spec.range_text(),
                        names.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
                    ),
                    found: format!(
                        "{given:?}{}",
                        did_you_mean(&lower, names.iter().map(|(n, _)| *n))
                    ),
                });
        }
        self.float_value(
            spec,
            value.as_ref(),
            default,
            [min, max],
            "a number or a name",
        )
    }

    /// The number `value` (or `default`) of parameter `spec`, in [min, max].
    fn float_value(
        &self,
        spec: &'static ParamSpec,
        value: Option<&Value>,
        default: Option<f32>,
        [min, max]: [f32; 2],
        expected: &str,
    ) -> Result<f32, PluginError> {
        let v = match value {
            None => default.ok_or_else(|| self.missing(spec, expected))? as f64,
            Some(v) => as_number(v).ok_or_else(|| self.wrong_type(spec.name, expected, v))?,
        };
        if !in_range(v, min, max) {
            return Err(self.bad_number(spec, &[v]));
        }
        Ok(v as f32)
    }

    pub fn int(&mut self, name: &str) -> Result<i64, PluginError> {
        let (spec, value) = self.take(name);
        let value = value.as_ref();
        let ParamKind::Int { default, min, max } = spec.kind else {
            panic!("parameter `{name}` is not declared as an integer");
        };
        let v = match value {
            None => default.ok_or_else(|| self.missing(spec, "an integer"))?,
            Some(v @ Value::Number(n)) => {
                let x = n.into_f64();
                if x.is_finite() && x.fract() != 0.0 {
                    return Err(self.wrong_type(name, "an integer", v));
                }
                // Checked before converting: `as i64` would saturate 1e23 to i64::MAX.
                if !(x >= min as f64 && x <= max as f64) {
                    return Err(self.bad_number(spec, &[x]));
                }
                x as i64
            }
            Some(v) => return Err(self.wrong_type(name, "an integer", v)),
        };
        if !(min..=max).contains(&v) {
            return Err(self.out_of_range(spec, v.to_string()));
        }
        Ok(v)
    }

    pub fn bool(&mut self, name: &str) -> Result<bool, PluginError> {
        let (spec, value) = self.take(name);
        let value = value.as_ref();
        let ParamKind::Bool { default } = spec.kind else {
            panic!("parameter `{name}` is not declared as a bool");
        };
        match value {
            None => default.ok_or_else(|| self.missing(spec, "true or false")),
            Some(Value::Bool(b)) => Ok(*b),
            Some(v) => Err(self.wrong_type(name, "true or false", v)),
        }
    }

    /// A linear RGB colour, each channel finite and in [0, max].
    pub fn rgb(&mut self, name: &str) -> Result<Vec3, PluginError> {
        let (spec, value) = self.take(name);
        let ParamKind::Rgb { default, max } = spec.kind else {
            panic!("parameter `{name}` is not declared as rgb");
        };
        self.rgb_value(
            spec,
            value.as_ref(),
            default,
            max,
            "an RGB triple (r, g, b) or one number",
        )
    }

    /// The colour `value` (or `default`) of parameter `spec`, each channel in [0, max].
    fn rgb_value(
        &self,
        spec: &'static ParamSpec,
        value: Option<&Value>,
        default: Option<[f32; 3]>,
        max: f32,
        expected: &str,
    ) -> Result<Vec3, PluginError> {
        let name = spec.name;
        let c = match value {
            None => default
                .ok_or_else(|| self.missing(spec, expected))?
                .map(f64::from),
            Some(v) => match (as_number(v), as_triple(v)) {
                (Some(grey), _) => [grey; 3],
                (_, Some(t)) => t,
                _ => return Err(self.wrong_type(name, expected, v)),
            },
        };
        if c.iter().any(|&x| !in_range(x, 0.0, max)) {
            return Err(self.bad_number(spec, &c));
        }
        Ok(Vec3::from(c.map(|x| x as f32)))
    }

    /// A finite 3D vector within the scene's coordinate range.
    pub fn vec3(&mut self, name: &str) -> Result<Vec3, PluginError> {
        let (spec, value) = self.take(name);
        let value = value.as_ref();
        let ParamKind::Vec3 { default } = spec.kind else {
            panic!("parameter `{name}` is not declared as a vector");
        };
        const EXPECTED: &str = "a vector (x, y, z)";
        let v = match value {
            None => default
                .ok_or_else(|| self.missing(spec, EXPECTED))?
                .map(f64::from),
            Some(v) => as_triple(v).ok_or_else(|| self.wrong_type(name, EXPECTED, v))?,
        };
        if v.iter()
            .any(|&x| !in_range(x, -MAX_COORDINATE, MAX_COORDINATE))
        {
            return Err(self.bad_number(spec, &v));
        }
        Ok(Vec3::from(v.map(|x| x as f32)))
    }

    /// An interval (lo, hi) with min <= lo <= hi <= max.
    pub fn interval(&mut self, name: &str) -> Result<[f32; 2], PluginError> {
        let (spec, value) = self.take(name);
        let value = value.as_ref();
        let ParamKind::Interval { default, min, max } = spec.kind else {
            panic!("parameter `{name}` is not declared as an interval");
        };
        let v = match value {
            None => default.map(f64::from),
            Some(v @ Value::Seq(s)) if s.len() == 2 => match (as_number(&s[0]), as_number(&s[1])) {
                (Some(lo), Some(hi)) => [lo, hi],
                _ => return Err(self.wrong_type(name, "an interval (lo, hi)", v)),
            },
            Some(v) => return Err(self.wrong_type(name, "an interval (lo, hi)", v)),
        };
        if !(in_range(v[0], min, max) && in_range(v[1], min, max)) {
            return Err(self.bad_number(spec, &v));
        }
        if v[0] > v[1] {
            return Err(PluginError::Invalid(format!(
                "parameter `{name}` of {} is the reversed interval {}: write (lo, hi) with lo <= hi",
                self.plugin,
                fmt_numbers(&v)
            )));
        }
        Ok(v.map(|x| x as f32))
    }

    fn string_value(&mut self, name: &str) -> Result<Option<String>, PluginError> {
        let (_, value) = self.take(name);
        let value = value.as_ref();
        match value {
            None => Ok(None),
            Some(Value::String(s)) => Ok(Some(s.clone())),
            Some(v) => Err(self.wrong_type(name, "a string", v)),
        }
    }

    pub fn string(&mut self, name: &str) -> Result<String, PluginError> {
        let spec = self.spec(name);
        let ParamKind::Str { default } = spec.kind else {
            panic!("parameter `{name}` is not declared as a string");
        };
        match self.string_value(name)? {
            Some(s) => Ok(s),
            None => default
                .map(str::to_string)
                .ok_or_else(|| self.missing(spec, "a string")),
        }
    }

    /// A required path, resolved against the scene file's directory.
    pub fn path(&mut self, name: &str) -> Result<PathBuf, PluginError> {
        let spec = self.spec(name);
        assert!(
            matches!(spec.kind, ParamKind::Path),
            "parameter `{name}` is not declared as a path"
        );
        let raw = self
            .string_value(name)?
            .ok_or_else(|| self.missing(spec, "a file path"))?;
        Ok(self.base_dir.join(raw))
    }

    /// One of the declared options.
    pub fn choice(&mut self, name: &str) -> Result<&'static str, PluginError> {
        let spec = self.spec(name);
        let ParamKind::Choice { options, default } = spec.kind else {
            panic!("parameter `{name}` is not declared as a choice");
        };
        let Some(given) = self.string_value(name)? else {
            return Ok(default);
        };
        options
            .iter()
            .copied()
            .find(|o| *o == given)
            .ok_or_else(|| PluginError::OutOfRange {
                plugin: self.plugin.clone(),
                name: name.to_string(),
                range: format!("one of {}", options.join(", ")),
                found: format!("{given:?}{}", did_you_mean(&given, options.iter().copied())),
            })
    }

    /// A list of distinct declared options (empty when not given).
    pub fn list(&mut self, name: &str) -> Result<Vec<&'static str>, PluginError> {
        let (spec, value) = self.take(name);
        let ParamKind::List { options } = spec.kind else {
            panic!("parameter `{name}` is not declared as a list");
        };
        let expected = format!("a list of names among {}", options.join(", "));
        let items = match value {
            None => return Ok(Vec::new()),
            Some(Value::Seq(items)) => items,
            Some(v) => return Err(self.wrong_type(name, &expected, &v)),
        };
        let mut chosen = Vec::new();
        for item in &items {
            let Value::String(given) = item else {
                return Err(self.wrong_type(name, &expected, item));
            };
            let option = options
                .iter()
                .copied()
                .find(|o| o == given)
                .ok_or_else(|| PluginError::OutOfRange {
                    plugin: self.plugin.clone(),
                    name: name.to_string(),
                    range: format!("any of {}", options.join(", ")),
                    found: format!("{given:?}{}", did_you_mean(given, options.iter().copied())),
                })?;
            if !chosen.contains(&option) {
                chosen.push(option);
            }
        }
        Ok(chosen)
    }

    /// Fails if a parameter was given but never read by the plugin (e.g. it does not apply to
    /// the chosen mode); `why` explains in the plugin's words.
    pub fn finish(self) -> Result<(), PluginError> {
        for name in self.values.keys() {
            if !self.used.iter().any(|u| u == name) {
                return Err(PluginError::Unused {
                    plugin: self.plugin.clone(),
                    name: name.clone(),
                    why: "it has no effect with the other settings given".into(),
                });
            }
        }
        Ok(())
    }
}

impl fmt::Debug for Params {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Params")
            .field("plugin", &self.plugin)
            .field("values", &self.values)
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    static SPECS: &[ParamSpec] = &[
        ParamSpec {
            name: "roughness",
            kind: ParamKind::Float {
                default: Some(0.1),
                min: 1e-4,
                max: 1.0,
            },
            unit: "",
            description: "GGX alpha",
        },
        ParamSpec {
            name: "reflectance",
            kind: ParamKind::Rgb {
                default: Some([0.5; 3]),
                max: 1.0,
            },
            unit: "",
            description: "albedo",
        },
        ParamSpec {
            name: "samples",
            kind: ParamKind::Int {
                default: None,
                min: 1,
                max: 1 << 20,
            },
            unit: "",
            description: "N",
        },
    ];

    fn params(text: &str) -> Result<Params, PluginError> {
        let map: BTreeMap<String, Value> = ron::from_str(text).unwrap();
        Params::new("bsdf `x` (test)", SPECS, map)
    }

    #[test]
    fn unknown_names_are_refused_with_a_suggestion() {
        let e = params(r#"{"roughnes": 0.2}"#).unwrap_err().to_string();
        assert!(e.contains("unknown parameter `roughnes`"), "{e}");
        assert!(e.contains("did you mean `roughness`"), "{e}");
        assert!(e.contains("bsdf `x` (test)"), "{e}");
    }

    #[test]
    fn defaults_types_and_ranges() {
        let mut p = params(r#"{"reflectance": 0.25, "samples": 8}"#).unwrap();
        assert_eq!(p.float("roughness").unwrap(), 0.1);
        assert_eq!(p.rgb("reflectance").unwrap(), Vec3::splat(0.25));
        assert_eq!(p.int("samples").unwrap(), 8);
        p.finish().unwrap();

        let mut p = params(r#"{"roughness": "big"}"#).unwrap();
        let e = p.float("roughness").unwrap_err().to_string();
        assert!(
            e.contains("expects a number, found the string \"big\""),
            "{e}"
        );

        let mut p = params(r#"{"roughness": 2.0}"#).unwrap();
        let e = p.float("roughness").unwrap_err().to_string();
        assert!(e.contains("must be in [0.0001, 1]"), "{e}");

        let mut p = params(r#"{}"#).unwrap();
        assert!(matches!(p.int("samples"), Err(PluginError::Missing { .. })));

        let mut p = params(r#"{"reflectance": (1, -1, 0)}"#).unwrap();
        assert!(p.rgb("reflectance").is_err());
        let mut p = params(r#"{"reflectance": (1, 1.5, 0)}"#).unwrap();
        let e = p.rgb("reflectance").unwrap_err().to_string();
        assert!(e.contains("must be in [0, 1] per channel"), "{e}");
    }

    static MORE: &[ParamSpec] = &[
        ParamSpec {
            name: "clamp",
            kind: ParamKind::Interval {
                default: [0.0, 1.0],
                min: 0.0,
                max: 1.0,
            },
            unit: "",
            description: "bounds",
        },
        ParamSpec {
            name: "position",
            kind: ParamKind::Vec3 { default: None },
            unit: "",
            description: "where",
        },
        ParamSpec {
            name: "count",
            kind: ParamKind::Int {
                default: Some(1),
                min: 1,
                max: 1 << 20,
            },
            unit: "",
            description: "how many",
        },
    ];

    fn more(text: &str) -> Params {
        Params::new("integrator `t`", MORE, ron::from_str(text).unwrap()).unwrap()
    }

    #[test]
    fn messages_name_the_real_fault() {
        // A huge integer is reported as written, not saturated to i64::MAX.
        let e = more(r#"{"count": 1e23}"#)
            .int("count")
            .unwrap_err()
            .to_string();
        assert!(e.contains("must be in [1, 1048576], found 1e23"), "{e}");
        let e = more(r#"{"count": 2.5}"#)
            .int("count")
            .unwrap_err()
            .to_string();
        assert!(e.contains("expects an integer"), "{e}");
        // A reversed interval says so, not that it is out of [0, 1].
        let e = more(r#"{"clamp": (0.9, 0.1)}"#)
            .interval("clamp")
            .unwrap_err()
            .to_string();
        assert!(e.contains("reversed interval (0.9, 0.1)"), "{e}");
        let e = more(r#"{"clamp": (NaN, 0.1)}"#)
            .interval("clamp")
            .unwrap_err()
            .to_string();
        assert!(e.contains("`clamp`") && e.contains("must be finite"), "{e}");
        // Vectors have a range in their message, and NaN is named.
        let e = more(r#"{"position": (NaN, 0, 0)}"#)
            .vec3("position")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`position`")
                && e.contains("(NaN, 0, 0)")
                && e.contains("[-1e12, 1e12] per"),
            "{e}"
        );
        let e = more(r#"{"position": (0, 2e12, 0)}"#)
            .vec3("position")
            .unwrap_err()
            .to_string();
        assert!(e.contains("must be in [-1e12, 1e12] per component"), "{e}");
        // A float beyond f32 is reported as written, not as inf.
        let mut p = params(r#"{"roughness": 1e39}"#).unwrap();
        let e = p.float("roughness").unwrap_err().to_string();
        assert!(e.contains("found 1e39"), "{e}");
        let mut p = params(r#"{"reflectance": (NaN, 0, 0)}"#).unwrap();
        let e = p.rgb("reflectance").unwrap_err().to_string();
        assert!(
            e.contains("`reflectance`") && e.contains("must be finite"),
            "{e}"
        );
    }

    #[test]
    fn given_but_unread_parameters_are_reported() {
        let mut p = params(r#"{"roughness": 0.3, "samples": 3}"#).unwrap();
        p.float("roughness").unwrap();
        let e = p.finish().unwrap_err().to_string();
        assert!(e.contains("`samples` is not used"), "{e}");
    }
}
