//! Support for the fuzz targets: the readers take paths, so each input is
//! written to a scratch file first (in `/dev/shm` when it exists, so the
//! write stays in memory), one directory per process.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use pd_io::Error;

/// This process's scratch directory, created on first use.
pub fn scratch_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = if Path::new("/dev/shm").is_dir() {
            PathBuf::from("/dev/shm")
        } else {
            std::env::temp_dir()
        };
        let dir = root.join(format!("pd-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create the scratch directory");
        dir
    })
}

/// Writes `bytes` to the scratch file `name` and returns its path.
pub fn scratch_file(name: &str, bytes: &[u8]) -> PathBuf {
    let path = scratch_dir().join(name);
    std::fs::write(&path, bytes).expect("write the scratch file");
    path
}

/// The number of lines of `bytes` as a reader counts them (a last line
/// without a newline counts).
pub fn line_count(bytes: &[u8]) -> usize {
    bytes.iter().filter(|&&b| b == b'\n').count() + 1
}

/// Checks the properties every error must have: a parse error names a line
/// of the file it came from and says something.
pub fn check_error(error: &Error, files: &[(&Path, usize)]) {
    let message = error.to_string();
    assert!(!message.trim().is_empty(), "empty error message");
    if let Error::Parse { path, line, .. } = error {
        let lines = files
            .iter()
            .find(|(p, _)| *p == path.as_path())
            .map(|(_, n)| *n)
            .unwrap_or_else(|| panic!("parse error names an unknown file {}", path.display()));
        assert!(
            (1..=lines).contains(line),
            "parse error at line {line} of a {lines}-line file: {message}"
        );
    }
}

/// Splits `data` at its first NUL byte (the second part is empty without one).
pub fn split_nul(data: &[u8]) -> (&[u8], &[u8]) {
    match data.iter().position(|&b| b == 0) {
        Some(at) => (&data[..at], &data[at + 1..]),
        None => (data, &[]),
    }
}
