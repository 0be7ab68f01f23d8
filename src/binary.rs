//! The binary files of distributed work (render shards, study cells): a magic string naming
//! the kind of file, a format version, then little-endian fields. Written atomically (a
//! temporary file beside the target, renamed), so that a crashed or killed job leaves either
//! the whole file or none; read with every field checked, errors naming the file and the
//! problem.

use anyhow::{Result, bail};
use std::path::{Path, PathBuf};

/// Builds a file's bytes.
pub struct Writer {
    bytes: Vec<u8>,
}

impl Writer {
    /// A file of kind `magic` (8 bytes) and format `version`.
    pub fn new(magic: &[u8; 8], version: u32) -> Self {
        let mut writer = Writer { bytes: Vec::new() };
        writer.bytes.extend_from_slice(magic);
        writer.u32(version);
        writer
    }

    pub fn u32(&mut self, v: u32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn u64(&mut self, v: u64) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f32(&mut self, v: f32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f64(&mut self, v: f64) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    /// A length-prefixed UTF-8 string.
    pub fn str(&mut self, s: &str) {
        self.u64(s.len() as u64);
        self.bytes.extend_from_slice(s.as_bytes());
    }

    pub fn f32s(&mut self, values: &[f32]) {
        self.u64(values.len() as u64);
        self.bytes.reserve(values.len() * 4);
        values.iter().for_each(|&v| self.f32(v));
    }

    pub fn f64s(&mut self, values: &[f64]) {
        self.u64(values.len() as u64);
        self.bytes.reserve(values.len() * 8);
        values.iter().for_each(|&v| self.f64(v));
    }

    pub fn u32s(&mut self, values: &[u32]) {
        self.u64(values.len() as u64);
        self.bytes.reserve(values.len() * 4);
        values.iter().for_each(|&v| self.u32(v));
    }

    /// Length-prefixed bytes.
    pub fn bytes(&mut self, values: &[u8]) {
        self.u64(values.len() as u64);
        self.bytes.extend_from_slice(values);
    }

    /// Writes the file atomically (creating its directory).
    pub fn write(self, path: &Path) -> Result<()> {
        let bytes = self.bytes;
        lumis_core::image_io::write_atomically(path, move |file| {
            std::io::Write::write_all(file, &bytes).map_err(|e| e.to_string())
        })?;
        Ok(())
    }
}

/// Reads a file's fields in order, each checked.
pub struct Reader {
    path: PathBuf,
    bytes: Vec<u8>,
    at: usize,
}

impl Reader {
    /// Opens `path`, which must be a file of kind `magic` (`what` names it in errors) and
    /// format `version`.
    pub fn open(path: &Path, magic: &[u8; 8], version: u32, what: &str) -> Result<Self> {
        let bytes = std::fs::read(path)
            .map_err(|e| anyhow::anyhow!("cannot read `{}`: {e}", path.display()))?;
        let mut reader = Reader {
            path: path.to_path_buf(),
            bytes,
            at: 0,
        };
        if reader.bytes.get(..8) != Some(magic.as_slice()) {
            bail!("`{}` is not a lumis {what} file", path.display());
        }
        reader.at = 8;
        let found = reader.u32("the format version")?;
        if found != version {
            bail!(
                "`{}` is a {what} file of format {found}; this lumis reads format {version} (re-run it with this version)",
                path.display()
            );
        }
        Ok(reader)
    }

    /// An error about this file.
    pub fn problem(&self, text: impl std::fmt::Display) -> anyhow::Error {
        anyhow::anyhow!("`{}`: {text}", self.path.display())
    }

    fn take(&mut self, n: usize, field: &str) -> Result<&[u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(self.problem(format!(
                "truncated: {field} needs {n} bytes at byte {}, the file has {}",
                self.at,
                self.bytes.len()
            )));
        };
        let slice = &self.bytes[self.at..end];
        self.at = end;
        Ok(slice)
    }

    pub fn u32(&mut self, field: &str) -> Result<u32> {
        let b = self.take(4, field)?;
        Ok(u32::from_le_bytes(b.try_into().expect("4 bytes")))
    }

    pub fn u64(&mut self, field: &str) -> Result<u64> {
        let b = self.take(8, field)?;
        Ok(u64::from_le_bytes(b.try_into().expect("8 bytes")))
    }

    pub fn f64(&mut self, field: &str) -> Result<f64> {
        Ok(f64::from_bits(self.u64(field)?))
    }

    /// A length within what is left of the file at `width` bytes per element.
    fn length(&mut self, width: usize, field: &str) -> Result<usize> {
        let n = self.u64(field)?;
        let left = (self.bytes.len() - self.at) as u64;
        if n.checked_mul(width as u64).is_none_or(|b| b > left) {
            return Err(self.problem(format!(
                "{field}: a length of {n} at byte {} runs past the end of the file",
                self.at - 8
            )));
        }
        Ok(n as usize)
    }

    pub fn str(&mut self, field: &str) -> Result<String> {
        let n = self.length(1, field)?;
        let bytes = self.take(n, field)?.to_vec();
        String::from_utf8(bytes).map_err(|_| self.problem(format!("{field} is not UTF-8")))
    }

    pub fn f32s(&mut self, field: &str) -> Result<Vec<f32>> {
        let n = self.length(4, field)?;
        let b = self.take(n * 4, field)?;
        Ok(b.chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect())
    }

    pub fn f64s(&mut self, field: &str) -> Result<Vec<f64>> {
        let n = self.length(8, field)?;
        let b = self.take(n * 8, field)?;
        Ok(b.chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect())
    }

    pub fn u32s(&mut self, field: &str) -> Result<Vec<u32>> {
        let n = self.length(4, field)?;
        let b = self.take(n * 4, field)?;
        Ok(b.chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect())
    }

    pub fn bytes(&mut self, field: &str) -> Result<Vec<u8>> {
        let n = self.length(1, field)?;
        Ok(self.take(n, field)?.to_vec())
    }

    /// Checks that every byte was read.
    pub fn finish(self) -> Result<()> {
        if self.at != self.bytes.len() {
            return Err(self.problem(format!(
                "{} bytes of garbage after the data, at byte {}",
                self.bytes.len() - self.at,
                self.at
            )));
        }
        Ok(())
    }
}
