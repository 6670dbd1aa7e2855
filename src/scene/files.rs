//! Reading the files a scene names, safely: only regular files, read no
//! further than their size; and the files a model refers to (glTF buffers
//! and images, OBJ material libraries) only from inside the model's folder.

use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// Why a file could not be read. The message names what was tried.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FileError {
    #[error("`{}` does not exist", path.display())]
    NotFound { path: PathBuf },
    #[error("`{}` is {kind}, not a regular file", path.display())]
    NotRegular { path: PathBuf, kind: &'static str },
    #[error("cannot read `{}`: {message}", path.display())]
    Io { path: PathBuf, message: String },
    #[error("`{reference}` is {why}; a model may refer only to files in its own folder")]
    Outside { reference: String, why: String },
}

impl FileError {
    /// What is wrong, without the path (for messages that name it already).
    pub fn reason(&self) -> String {
        match self {
            FileError::NotFound { .. } => "not found".into(),
            FileError::NotRegular { kind, .. } => format!("it is {kind}, not a regular file"),
            FileError::Io { message, .. } => message.clone(),
            FileError::Outside { .. } => self.to_string(),
        }
    }
}

/// Reads the whole of the regular file at `path` (symbolic links followed).
/// Devices, FIFOs, sockets and folders are refused before anything is read
/// (`/dev/zero` would never end), and no more bytes are read than the size
/// the file had when opened; the buffer is reserved fallibly, so a file
/// larger than the memory available is an error, not an abort.
pub fn read_regular_file(path: &Path) -> Result<Vec<u8>, FileError> {
    let io = |e: std::io::Error| match e.kind() {
        std::io::ErrorKind::NotFound => FileError::NotFound {
            path: path.to_path_buf(),
        },
        _ => FileError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        },
    };
    // Refuse special files before opening them: opening a FIFO blocks until
    // someone writes to it.
    let kind = std::fs::metadata(path).map_err(io)?;
    if !kind.is_file() {
        return Err(FileError::NotRegular {
            path: path.to_path_buf(),
            kind: file_kind(&kind),
        });
    }
    let file = std::fs::File::open(path).map_err(io)?;
    // Checked again on what was opened, in case the path changed meanwhile.
    let meta = file.metadata().map_err(io)?;
    if !meta.is_file() {
        return Err(FileError::NotRegular {
            path: path.to_path_buf(),
            kind: file_kind(&meta),
        });
    }
    let size = meta.len();
    let mut data = Vec::new();
    usize::try_from(size)
        .ok()
        .and_then(|n| data.try_reserve_exact(n).ok())
        .ok_or_else(|| FileError::Io {
            path: path.to_path_buf(),
            message: format!("{size} bytes do not fit in memory"),
        })?;
    file.take(size).read_to_end(&mut data).map_err(io)?;
    Ok(data)
}

/// [`read_regular_file`] as text; invalid UTF-8 is replaced (comments and
/// names in files from elsewhere are often Latin-1).
pub fn read_text_file(path: &Path) -> Result<String, FileError> {
    let data = read_regular_file(path)?;
    Ok(match String::from_utf8(data) {
        Ok(s) => s,
        Err(e) => String::from_utf8_lossy(e.as_bytes()).into_owned(),
    })
}

fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if meta.is_dir() {
        "a folder"
    } else {
        "a special file"
    }
}

/// The path of a file that a model in `folder` refers to as `reference`
/// (already decoded from any URI escaping). Accepted: relative paths that
/// stay inside `folder`, also after symbolic links are resolved. Refused,
/// naming the reference: absolute paths, URI schemes (`file:`, `http:`, …)
/// and Windows drive or UNC paths, paths that climb out with `..`, and
/// links that lead outside. A reference to a file that does not exist
/// inside the folder gives [`FileError::NotFound`] with the path tried.
pub fn resolve_inside(folder: &Path, reference: &str) -> Result<PathBuf, FileError> {
    let outside = |why: &str| FileError::Outside {
        reference: reference.to_string(),
        why: why.to_string(),
    };
    if reference.is_empty() {
        return Err(outside("empty"));
    }
    if reference.contains('\0') {
        return Err(outside("not a valid file name"));
    }
    if has_scheme(reference) {
        return Err(outside("a URI with a scheme"));
    }
    let relative = Path::new(reference);
    if relative.is_absolute() || reference.starts_with(['/', '\\']) {
        return Err(outside("an absolute path"));
    }
    // Lexically first: `a/../../x` climbs out even if `a` does not exist.
    let mut depth = 0i32;
    for c in relative.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::ParentDir => {
                depth -= 1;
                if depth < 0 {
                    return Err(outside("outside the model's folder"));
                }
            }
            Component::CurDir => {}
            Component::RootDir | Component::Prefix(_) => {
                return Err(outside("an absolute path"));
            }
        }
    }
    let joined = folder.join(relative);
    let real_folder = std::fs::canonicalize(if folder.as_os_str().is_empty() {
        Path::new(".")
    } else {
        folder
    })
    .map_err(|e| FileError::Io {
        path: folder.to_path_buf(),
        message: e.to_string(),
    })?;
    let real = match std::fs::canonicalize(&joined) {
        Ok(p) => p,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(FileError::NotFound { path: joined });
        }
        Err(e) => {
            return Err(FileError::Io {
                path: joined,
                message: e.to_string(),
            });
        }
    };
    if !real.starts_with(&real_folder) {
        return Err(outside(&format!(
            "a link to `{}`, outside the model's folder",
            real.display()
        )));
    }
    Ok(real)
}

/// Whether `s` starts with a URI scheme (`file:`, `http:`) or a Windows drive
/// (`C:`): letters, digits, `+ - .`, then a colon, before any slash.
fn has_scheme(s: &str) -> bool {
    match s.find(':') {
        Some(i) => {
            let head = &s[..i];
            !head.is_empty()
                && head.starts_with(|c: char| c.is_ascii_alphabetic())
                && head
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
        }
        None => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn special_files_are_refused_before_reading() {
        #[cfg(unix)]
        {
            let e = read_regular_file(Path::new("/dev/zero")).unwrap_err();
            assert!(
                e.to_string().contains("/dev/zero` is a character device"),
                "{e}"
            );
        }
        let dir = tempfile::tempdir().unwrap();
        let e = read_regular_file(dir.path()).unwrap_err();
        assert!(matches!(
            e,
            FileError::NotRegular {
                kind: "a folder",
                ..
            }
        ));
        let missing = dir.path().join("nothing.ply");
        assert_eq!(
            read_regular_file(&missing).unwrap_err(),
            FileError::NotFound { path: missing }
        );
        let file = dir.path().join("a.txt");
        std::fs::write(&file, "hello").unwrap();
        assert_eq!(read_regular_file(&file).unwrap(), b"hello");
    }

    #[test]
    fn references_stay_inside_the_folder() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("model");
        std::fs::create_dir_all(folder.join("sub")).unwrap();
        std::fs::write(folder.join("sub/a.bin"), "x").unwrap();
        std::fs::write(dir.path().join("secret.bin"), "x").unwrap();
        let inside = resolve_inside(&folder, "sub/../sub/a.bin").unwrap();
        assert!(inside.ends_with("sub/a.bin"));
        for bad in [
            "../secret.bin",
            "sub/../../secret.bin",
            "/etc/passwd",
            "file:///etc/passwd",
            "http://example.com/a.bin",
            "C:\\Windows\\win.ini",
            "\\\\server\\share",
            "",
        ] {
            let e = resolve_inside(&folder, bad).unwrap_err();
            assert!(matches!(e, FileError::Outside { .. }), "{bad}: {e}");
            assert!(e.to_string().contains(&format!("`{bad}`")), "{e}");
        }
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(dir.path().join("secret.bin"), folder.join("link.bin"))
                .unwrap();
            let e = resolve_inside(&folder, "link.bin").unwrap_err();
            assert!(e.to_string().contains("outside the model's folder"), "{e}");
        }
        let e = resolve_inside(&folder, "missing.bin").unwrap_err();
        assert_eq!(
            e,
            FileError::NotFound {
                path: folder.join("missing.bin")
            }
        );
    }
}
