//! Errors of scene loading and output, each naming the file (and position) it concerns.

use std::fmt;
use std::path::{Path, PathBuf};

/// A problem with a scene or one of the files it refers to.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// The file the problem is in: the scene file, or an asset it refers to.
    pub file: PathBuf,
    /// 1-based line and column, when the problem has a position in a text file.
    pub position: Option<(usize, usize)>,
    pub message: String,
}

impl SceneError {
    pub fn new(file: impl AsRef<Path>, message: impl Into<String>) -> Self {
        SceneError {
            file: file.as_ref().to_path_buf(),
            position: None,
            message: message.into(),
        }
    }

    pub fn at(file: impl AsRef<Path>, line: usize, col: usize, message: impl Into<String>) -> Self {
        SceneError {
            file: file.as_ref().to_path_buf(),
            position: Some((line, col)),
            message: message.into(),
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some((line, col)) = self.position {
            write!(f, ":{line}:{col}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for SceneError {}

/// The name among `candidates` closest to `name`, if any is close enough to be a likely typo.
pub fn closest_name<'a>(
    name: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| {
            (
                strsim::normalized_damerau_levenshtein(&name.to_lowercase(), &c.to_lowercase()),
                c,
            )
        })
        .filter(|(score, _)| *score >= 0.5)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, c)| c)
}

/// " (did you mean `x`?)" or nothing.
pub fn did_you_mean<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> String {
    closest_name(name, candidates)
        .map(|c| format!(" (did you mean `{c}`?)"))
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggests_close_names_only() {
        assert_eq!(
            closest_name("difuse", ["diffuse", "glossy"]),
            Some("diffuse")
        );
        assert_eq!(
            closest_name("Balanse", ["balance", "power"]),
            Some("balance")
        );
        assert_eq!(closest_name("xyz", ["diffuse", "glossy"]), None);
    }

    #[test]
    fn display_names_file_and_position() {
        let e = SceneError::at("a/b.ron", 3, 7, "expected `,`");
        assert_eq!(e.to_string(), "a/b.ron:3:7: expected `,`");
    }
}
