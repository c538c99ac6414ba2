//! Writing output files safely: never over an input, never half-written, and checked before a
//! long task that ends by writing them ([`ensure_writable`], [`same_file`]).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use tempfile::NamedTempFile;

use crate::error::{Error, Result};

/// Write `bytes` to `path` atomically: into a temporary file in the same folder, flushed to disk,
/// then renamed over `path`. A crash or a full disk leaves either the old file or the new one,
/// never a mix. A file replaced keeps its permissions; a new one gets ordinary ones (0644 on
/// Unix).
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically_with_mode(path, bytes, ordinary_mode(path))
}

/// [`write_atomically`], the file getting the Unix permission bits `mode` (ignored elsewhere).
///
/// The temporary file is created private to its owner (0600, `tempfile`'s default on Unix) and
/// given `mode` before the rename,
/// so a file written with 0600 (a secret) is never readable by others, not even for a moment.
pub fn write_atomically_with_mode(path: &Path, bytes: &[u8], mode: u32) -> Result<()> {
    atomic_write(path, mode, |w| {
        w.write_all(bytes).map_err(|e| Error::File {
            path: path.to_owned(),
            message: format!("cannot write: {e}"),
        })
    })
}

/// [`write_atomically`], the content written by `write` into a buffered writer (so a large
/// output is never held whole in memory): the file is replaced only when `write` succeeds, and
/// its error is returned as it is.
pub fn write_atomically_with<T, E: From<Error>>(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&mut File>) -> std::result::Result<T, E>,
) -> std::result::Result<T, E> {
    atomic_write(path, ordinary_mode(path), write)
}

/// The permission bits an ordinary output gets: those of the file it replaces (whoever could
/// read it before can, and no one else), 0644 for a new one.
fn ordinary_mode(path: &Path) -> u32 {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        if let Ok(meta) = std::fs::metadata(path) {
            // The permission bits alone: a data file has no use for setuid, setgid or sticky,
            // and the new file may belong to someone else (a run with sudo).
            return meta.permissions().mode() & 0o777;
        }
    }
    #[cfg(not(unix))]
    let _ = path;
    0o644
}

/// Flush the folder of a file just renamed into it, so that a power cut after the write was
/// reported done cannot bring the old file back. Best effort: the file is in place by then, and
/// some file systems cannot flush a folder (Unix only; elsewhere the system's rename is left as
/// it is).
fn sync_folder(path: &Path) {
    #[cfg(unix)]
    if let Ok(folder) = File::open(folder_of(path)) {
        let _ = folder.sync_all();
    }
    #[cfg(not(unix))]
    let _ = path;
}

/// Write a temporary file in `path`'s folder with `write`, give it `mode`, flush it to disk and
/// rename it over `path`; on any error the temporary file is removed.
fn atomic_write<T, E: From<Error>>(
    path: &Path,
    mode: u32,
    write: impl FnOnce(&mut BufWriter<&mut File>) -> std::result::Result<T, E>,
) -> std::result::Result<T, E> {
    let file_error = file_error(path);
    let mut tmp = temporary_beside(path, "").map_err(file_error)?;
    let _unfinished = Unfinished::register(tmp.path());
    let mut writer = BufWriter::new(tmp.as_file_mut());
    let value = write(&mut writer)?;
    writer
        .flush()
        .map_err(|e| file_error(format!("cannot write: {e}")))?;
    drop(writer);
    put_in_place(tmp, path, mode)?;
    Ok(value)
}

/// [`write_atomically`] for a writer that wants a file name of its own to write to (a plotting
/// library's file backend, which picks the format by the extension): `write` is given the path
/// of a temporary file in `path`'s folder, ending with `suffix`, which then replaces `path` as
/// any output does (its permissions, the flushes, the clean-up after Ctrl-C).
pub fn write_atomically_at<T, E: From<Error>>(
    path: &Path,
    suffix: &str,
    write: impl FnOnce(&Path) -> std::result::Result<T, E>,
) -> std::result::Result<T, E> {
    let tmp = temporary_beside(path, suffix).map_err(file_error(path))?;
    let _unfinished = Unfinished::register(tmp.path());
    // What `write` wrote through a handle of its own is flushed through this one: the same file.
    let value = write(tmp.path())?;
    put_in_place(tmp, path, ordinary_mode(path))?;
    Ok(value)
}

/// Give a written temporary file `mode`, flush it to disk and rename it over `path`, then flush
/// the folder.
fn put_in_place(tmp: NamedTempFile, path: &Path, mode: u32) -> Result<()> {
    let file_error = file_error(path);
    set_mode(tmp.as_file(), mode)
        .and_then(|()| tmp.as_file().sync_all())
        .map_err(|e| file_error(format!("cannot write: {e}")))?;
    tmp.persist(path)
        .map_err(|e| file_error(format!("cannot replace the file: {}", e.error)))?;
    sync_folder(path);
    Ok(())
}

/// The temporary files being written now, for [`remove_unfinished_outputs`].
static UNFINISHED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A temporary file registered as being written, until this guard is dropped (renamed into place,
/// or removed on an error, by then).
struct Unfinished(PathBuf);

impl Unfinished {
    fn register(path: &Path) -> Self {
        if let Ok(mut paths) = UNFINISHED.lock() {
            paths.push(path.to_owned());
        }
        Unfinished(path.to_owned())
    }
}

impl Drop for Unfinished {
    fn drop(&mut self) {
        if let Ok(mut paths) = UNFINISHED.lock() {
            paths.retain(|p| *p != self.0);
        }
    }
}

/// Remove the temporary files of the outputs being written now: for an interrupted program
/// (Ctrl-C) that exits at once, whose temporary files would otherwise be left beside the outputs
/// (the outputs themselves are never touched: they are replaced only by a finished file).
pub fn remove_unfinished_outputs() {
    remove_unfinished_where(|_| true);
}

/// [`remove_unfinished_outputs`] for the temporary files `which` picks.
fn remove_unfinished_where(which: impl Fn(&Path) -> bool) {
    let paths = match UNFINISHED.lock() {
        Ok(paths) => paths.clone(),
        Err(poisoned) => poisoned.into_inner().clone(),
    };
    for path in paths.iter().filter(|p| which(p)) {
        let _ = std::fs::remove_file(path);
    }
}

/// The folder a file at `path` goes into (`.` for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A new temporary file in `path`'s folder, or why not, in words: a folder that does not exist
/// or is not a folder is named as such (not as the temporary file's path).
fn temporary_beside(path: &Path, suffix: &str) -> std::result::Result<NamedTempFile, String> {
    let dir = folder_of(path);
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(format!("the directory {} does not exist", dir.display()));
        }
        Ok(m) if !m.is_dir() => {
            return Err(format!("{} is not a directory", dir.display()));
        }
        _ => {}
    }
    tempfile::Builder::new()
        .prefix(".kerfmeter-")
        .suffix(suffix)
        .tempfile_in(dir)
        .map_err(|e| {
            use std::io::ErrorKind as Kind;
            // The common reasons in words, without the temporary file's made-up name that
            // `tempfile` adds to its error.
            let reason = match (e.kind(), e.raw_os_error()) {
                (
                    kind @ (Kind::PermissionDenied
                    | Kind::ReadOnlyFilesystem
                    | Kind::StorageFull
                    | Kind::QuotaExceeded),
                    _,
                ) => kind.to_string(),
                // The folder exists (checked above), so "no such file" means that it takes no
                // new files, as /proc and /sys do.
                (Kind::NotFound, _) => "it does not take new files".to_owned(),
                (_, Some(code)) => std::io::Error::from_raw_os_error(code).to_string(),
                _ => e.kind().to_string(),
            };
            let dir = dir.display();
            format!("cannot create a file in the directory {dir}: {reason}")
        })
}

/// Check, before a long task that ends by writing `path`, that it can be written there: its
/// directory exists and takes a new file (a temporary file is created in it and removed).
pub fn ensure_writable(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(file_error(path)(
            "is a directory: give a file name for the output".into(),
        ));
    }
    temporary_beside(path, "")
        .map(drop)
        .map_err(file_error(path))
}

/// The error of a file at `path`, from what went wrong with it.
fn file_error(path: &Path) -> impl Fn(String) -> Error + Copy + '_ {
    |message| Error::File {
        path: path.to_owned(),
        message,
    }
}

/// `path` as compared by [`same_file`]: canonical when it exists, else its directory's canonical
/// path with its name when that exists, else made absolute (lexically normalised).
fn comparable(path: &Path) -> PathBuf {
    if let Ok(p) = path.canonicalize() {
        return p;
    }
    if let (Ok(dir), Some(name)) = (folder_of(path).canonicalize(), path.file_name()) {
        return dir.join(name);
    }
    std::path::absolute(path).unwrap_or_else(|_| path.to_owned())
}

/// True when `a` and `b` name the same file, whether or not it exists yet (`out.svg` and
/// `./out.svg` do; so do a file and a link to it).
pub fn same_file(a: &Path, b: &Path) -> bool {
    comparable(a) == comparable(b)
}

/// Give an open file the Unix permission bits `mode` (nothing elsewhere).
fn set_mode(file: &std::fs::File, mode: u32) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        file.set_permissions(std::fs::Permissions::from_mode(mode))
    }
    #[cfg(not(unix))]
    {
        let _ = (file, mode);
        Ok(())
    }
}

/// Refuse to write `output` when it is the same file as `input` (the user's input is never
/// overwritten).
pub fn ensure_not_input(input: &Path, output: &Path) -> Result<()> {
    if same_file(input, output) {
        return Err(Error::invalid(format!(
            "the output {} is the input file; choose another output path (inputs are never overwritten)",
            output.display()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_interrupted_write_leaves_no_temporary_file_and_the_output_as_it_was() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.svg");
        std::fs::write(&out, "earlier").unwrap();
        let written = write_atomically_with(&out, |w| -> Result<()> {
            w.write_all(b"half").unwrap();
            w.flush().unwrap();
            // Interrupted here (what a Ctrl-C handler does before it exits; only this test's
            // folder, as other tests write beside it).
            remove_unfinished_where(|p| p.starts_with(dir.path()));
            // The temporary file is gone while the write is under way: only the output is left.
            assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
            Ok(())
        });
        // Its temporary file gone, the write cannot complete.
        assert!(written.is_err(), "{written:?}");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["out.svg"]);
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "earlier");
        let registered = UNFINISHED.lock().unwrap().clone();
        assert!(!registered.iter().any(|p| p.starts_with(dir.path())));
    }

    #[test]
    fn writes_and_replaces_atomically() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.txt");
        write_atomically(&p, b"one").unwrap();
        write_atomically(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode(&p), 0o644);
            // A file the user made private (or shared with a group) keeps that when replaced.
            for kept in [0o600, 0o664] {
                std::fs::set_permissions(&p, std::fs::Permissions::from_mode(kept)).unwrap();
                write_atomically(&p, b"three").unwrap();
                assert_eq!(mode(&p), kept);
            }
        }
        // No temporary files left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_writer_given_a_path_replaces_the_output_the_same_way() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("curve.png");
        std::fs::write(&p, "old").unwrap();
        let written = write_atomically_at(&p, ".png", |tmp: &Path| -> Result<PathBuf> {
            assert_eq!(tmp.extension().unwrap(), "png");
            assert_eq!(tmp.parent(), Some(dir.path()));
            std::fs::write(tmp, "new").unwrap();
            Ok(tmp.to_owned())
        })
        .unwrap();
        assert!(!written.exists(), "renamed into place");
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "new");
        let failed = write_atomically_at(&p, ".png", |tmp: &Path| -> Result<()> {
            std::fs::write(tmp, "half").unwrap();
            Err(Error::invalid("drawing failed"))
        });
        assert!(failed.is_err());
        assert_eq!(
            std::fs::read_to_string(&p).unwrap(),
            "new",
            "kept on failure"
        );
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[cfg(unix)]
    #[test]
    fn a_private_file_is_never_readable_by_others() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("secret.json");
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        // Over a file readable by others, too: the new file does not inherit its mode.
        std::fs::write(&p, "old").unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o644)).unwrap();
        write_atomically_with_mode(&p, b"secret", 0o600).unwrap();
        assert_eq!(mode(&p), 0o600);
        assert_eq!(std::fs::read(&p).unwrap(), b"secret");
        write_atomically_with_mode(&p, b"secret 2", 0o600).unwrap();
        assert_eq!(mode(&p), 0o600);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn an_output_equal_to_the_input_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("in.svg");
        std::fs::write(&p, "x").unwrap();
        assert!(ensure_not_input(&p, &p).is_err());
        assert!(ensure_not_input(&p, &dir.path().join("out.svg")).is_ok());
    }

    #[test]
    fn the_same_file_is_found_by_different_names_existing_or_not() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("sub")).unwrap();
        // Not written yet: the same name through `.` and `..`.
        assert!(same_file(&d.join("out.svg"), &d.join("sub/../out.svg")));
        assert!(same_file(&d.join("out.svg"), &d.join("./out.svg")));
        assert!(!same_file(&d.join("out.svg"), &d.join("out.gcode")));
        std::fs::write(d.join("out.svg"), "x").unwrap();
        assert!(same_file(&d.join("out.svg"), &d.join("sub/../out.svg")));
        assert!(same_file(Path::new("a.svg"), Path::new("./a.svg")));
    }

    #[test]
    fn an_output_in_a_missing_directory_is_named_as_such() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nodir");
        let out = missing.join("o.gcode");
        let e = ensure_writable(&out).unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "the directory {} does not exist",
                missing.display()
            )),
            "{e}"
        );
        let e = write_atomically(&out, b"x").unwrap_err().to_string();
        assert!(
            e.contains("does not exist") && !e.contains(".kerfmeter-"),
            "{e}"
        );
        std::fs::write(&missing, "a file").unwrap();
        let e = ensure_writable(&out).unwrap_err().to_string();
        assert!(e.contains("is not a directory"), "{e}");
        // A directory that exists: checked, and nothing left in it.
        ensure_writable(&dir.path().join("o.gcode")).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
