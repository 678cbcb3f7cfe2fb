//! Atomic file replacement, which every writer of this crate uses: an
//! interrupted run (Ctrl-C, a crash, a full disk) never leaves a
//! half-written file under its final name.

use std::ffi::OsString;
use std::fs::File;
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Writes a file atomically: `write` fills a buffered temporary file
/// `.NAME.tmp` in the target's directory, which is then flushed and renamed
/// to `path`. If `write` or any step fails, the temporary file is removed
/// and an existing file at `path` is left untouched.
///
/// The rename makes the write atomic with respect to crashes and
/// interruptions of this process; the data is not `fsync`ed, because doing
/// so for every frame costs far more than it protects against (a power cut
/// mid-run loses the run anyway). Two writers must not target the same path
/// at the same time, as they would share the temporary name.
///
/// # Errors
/// [`Error::Io`] naming `path` (not the temporary file), for any failure.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> Result<()> {
    let temporary = temporary_path(path)?;
    let result = File::create(&temporary).and_then(|file| {
        let mut writer = BufWriter::new(file);
        write(&mut writer)?;
        writer
            .into_inner()
            .map_err(io::IntoInnerError::into_error)?;
        std::fs::rename(&temporary, path)
    });
    result.map_err(|source| {
        // Best effort: the temporary may not exist if creating it failed,
        // and the error that matters is the one we return.
        let _ = std::fs::remove_file(&temporary);
        Error::io(path, source)
    })
}

/// `dir/.NAME.tmp` for `dir/NAME`: hidden, in the same directory (so the
/// final rename never crosses file systems).
fn temporary_path(path: &Path) -> Result<PathBuf> {
    let Some(name) = path.file_name() else {
        return Err(Error::io(
            path,
            io::Error::new(io::ErrorKind::InvalidInput, "not a file name"),
        ));
    };
    let mut temporary_name = OsString::from(".");
    temporary_name.push(name);
    temporary_name.push(".tmp");
    Ok(path.with_file_name(temporary_name))
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use super::*;

    fn scratch_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pd-io-atomic-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn failed_write_keeps_the_old_file_and_leaves_no_temporary() {
        let dir = scratch_dir("failed-write");
        let path = dir.join("frame.obj");
        std::fs::write(&path, "old contents\n").unwrap();
        let err = write_atomically(&path, |w| {
            w.write_all(b"half a fra")?;
            Err(io::Error::other("interrupted"))
        })
        .unwrap_err();
        assert!(
            matches!(&err, Error::Io { path: p, .. } if *p == path),
            "{err}"
        );
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old contents\n");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn successful_write_replaces_the_old_file() {
        let dir = scratch_dir("replace");
        let path = dir.join("state.json");
        std::fs::write(&path, "old").unwrap();
        write_atomically(&path, |w| w.write_all(b"new")).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_path_without_file_name_is_an_io_error() {
        let err = write_atomically(Path::new("/"), |_| Ok(())).unwrap_err();
        assert!(matches!(err, Error::Io { .. }), "{err}");
    }
}
