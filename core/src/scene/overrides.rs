//! `--set path=value`: overrides of any scene field by its path, applied to the parsed document.
//!
//! Paths name struct fields and map keys with dots and list elements with `[i]`:
//! `integrator.type=power`, `integrator.samples=64`, `film.width=128`,
//! `bsdfs.red.reflectance=(0.8, 0.1, 0.1)`, `shapes[2].emitter.radiance=10`.

use ron::Value;

/// One parsed `path=value` override.
#[derive(Clone, Debug, PartialEq)]
pub struct Override {
    pub path: Vec<PathStep>,
    pub value: Value,
    /// The text as given, for messages.
    pub text: String,
}

#[derive(Clone, Debug, PartialEq)]
pub enum PathStep {
    Key(String),
    Index(usize),
}

impl Override {
    /// Parses `a.b[2].c=value`; the value is RON (`64`, `(1, 0, 0)`, `"text"`) or, when it is
    /// not valid RON or a bare word, a string (`integrator.type=power`).
    pub fn parse(text: &str) -> Result<Self, String> {
        let (path, value) = text
            .split_once('=')
            .ok_or_else(|| format!("`--set {text}`: expected path=value"))?;
        let mut steps = Vec::new();
        for part in path.trim().split('.') {
            let (key, mut rest) = match part.find('[') {
                Some(i) => (&part[..i], &part[i..]),
                None => (part, ""),
            };
            if key.is_empty() && rest.is_empty() {
                return Err(format!("`--set {text}`: empty path component"));
            }
            if !key.is_empty() {
                steps.push(PathStep::Key(key.to_string()));
            }
            while let Some(stripped) = rest.strip_prefix('[') {
                let (index, after) = stripped
                    .split_once(']')
                    .ok_or_else(|| format!("`--set {text}`: missing `]`"))?;
                let index = index
                    .parse()
                    .map_err(|_| format!("`--set {text}`: `{index}` is not a list index"))?;
                steps.push(PathStep::Index(index));
                rest = after;
            }
            if !rest.is_empty() {
                return Err(format!("`--set {text}`: unexpected `{rest}` in the path"));
            }
        }
        let raw = value.trim();
        let value = match ron::from_str::<Value>(raw) {
            Ok(Value::Unit) | Err(_) => Value::String(raw.to_string()),
            Ok(v) => v,
        };
        Ok(Override {
            path: steps,
            value,
            text: text.to_string(),
        })
    }

    /// Sets the value in `doc`, creating missing map entries (so optional fields can be set).
    pub fn apply(&self, doc: &mut Value) -> Result<(), String> {
        let mut node = doc;
        for step in &self.path {
            node = match (step, node) {
                (PathStep::Key(k), Value::Map(map)) => {
                    let key = Value::String(k.clone());
                    if map.get(&key).is_none() {
                        map.insert(key.clone(), Value::Map(Default::default()));
                    }
                    map.get_mut(&key)
                        .ok_or_else(|| format!("`--set {}`: cannot set `{k}`", self.text))?
                }
                (PathStep::Index(i), Value::Seq(list)) => {
                    let len = list.len();
                    list.get_mut(*i).ok_or_else(|| {
                        format!(
                            "`--set {}`: index {i} is out of range (the list has {len})",
                            self.text
                        )
                    })?
                }
                (PathStep::Key(k), _) => {
                    return Err(format!(
                        "`--set {}`: `{k}` is not inside a struct or map",
                        self.text
                    ));
                }
                (PathStep::Index(i), _) => {
                    return Err(format!("`--set {}`: [{i}] is not inside a list", self.text));
                }
            };
        }
        *node = self.value.clone();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_paths_and_values() {
        let o = Override::parse("shapes[2].emitter.radiance=(1, 2, 3)").unwrap();
        assert_eq!(
            o.path,
            vec![
                PathStep::Key("shapes".into()),
                PathStep::Index(2),
                PathStep::Key("emitter".into()),
                PathStep::Key("radiance".into())
            ]
        );
        assert!(matches!(o.value, Value::Seq(ref s) if s.len() == 3));
        let o = Override::parse("integrator.type=power").unwrap();
        assert_eq!(o.value, Value::String("power".into()));
        assert!(Override::parse("integrator.type").is_err());
        assert!(Override::parse("a[x]=1").is_err());
    }
}
