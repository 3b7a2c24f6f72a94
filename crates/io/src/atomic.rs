//! Atomic output files: write to a temporary file in the target's directory, then rename.
//!
//! If anything fails before [`AtomicFile::commit`], the temporary file is removed on drop and
//! the target is untouched, so bad input never leaves a partial output file.
//!
//! Temporary files are also removed when the process is interrupted: every live temporary path
//! is kept in a process-wide registry, and the first [`AtomicFile::create`] installs a handler for
//! SIGINT, SIGTERM and SIGHUP (the `signal-hook` crate: its handler only writes to a pipe, and a
//! small thread does the work outside signal context, where taking a lock and unlinking files is
//! allowed) that removes them and then lets the signal end the process the default way (so the
//! exit status still says "killed by SIGINT"). [`remove_all_temporaries`] does the same for a
//! caller that exits without unwinding.
//!
//! [`AtomicFile::create`] checks the output path first: a missing directory, a path that is a
//! directory, or a directory that cannot be written is an [`OutputError::Path`] naming the path
//! (bad usage, exit 2), not an I/O failure.
//!
//! What an output may replace (one policy for every command, [`check_output_path`], checked at
//! [`AtomicFile::create`] and again just before the rename of [`AtomicFile::commit`]): only a
//! regular file. A symbolic link, a character or block device, a FIFO or a socket at the
//! output path is refused (the rename would replace the link or the device node by a regular
//! file), and so is a file that is one of the command's own inputs: every reader of
//! `truepos-io` records what it opens ([`note_input`]: device and inode, so another name for
//! the same file — a hard link, `./x`, a path through a symlinked directory — is recognised).

use crate::InputError;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, Once};

/// An output file that could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The path itself cannot be an output (missing directory, a directory, no permission):
    /// the user's choice of path, exit 2.
    #[error("{0}")]
    Path(InputError),
    /// Writing, syncing or renaming failed (disk full, I/O error).
    #[error("cannot write {}: {source}", path.display())]
    Io {
        /// The file being written.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: io::Error,
    },
}

impl OutputError {
    /// True when the output path itself is the problem (bad usage rather than a failure).
    pub fn is_path(&self) -> bool {
        matches!(self, OutputError::Path(_))
    }

    /// The output error of a writer that returns `std::io::Result` for `path`: the
    /// [`OutputError`] riding inside the `io::Error` when there is one, else a failed write.
    pub fn from_io(path: &Path, e: io::Error) -> OutputError {
        if !e.get_ref().is_some_and(|i| i.is::<OutputError>()) {
            return OutputError::Io { path: path.to_path_buf(), source: e };
        }
        let kind = e.kind();
        match e.into_inner().map(|i| i.downcast::<OutputError>()) {
            Some(Ok(o)) => *o,
            Some(Err(other)) => {
                OutputError::Io { path: path.to_path_buf(), source: io::Error::new(kind, other) }
            }
            None => OutputError::Io { path: path.to_path_buf(), source: kind.into() },
        }
    }
}

/// For callers that return `std::io::Result`: the output error rides inside the `io::Error`
/// (`get_ref()` gives it back, so a binary can still tell a bad path from a failed write).
impl From<OutputError> for io::Error {
    fn from(e: OutputError) -> Self {
        let kind = match &e {
            OutputError::Path(_) => io::ErrorKind::InvalidInput,
            OutputError::Io { source, .. } => source.kind(),
        };
        io::Error::new(kind, e)
    }
}

/// Temporary paths of live [`AtomicFile`]s (created, neither committed nor dropped).
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
static HANDLER: Once = Once::new();

fn live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // A panic while the lock was held leaves a plain list behind: still usable.
    LIVE.lock().unwrap_or_else(|p| p.into_inner())
}

/// Remove every live temporary file (the signal handler does this before the process ends).
/// Returns how many were removed.
pub fn remove_all_temporaries() -> usize {
    let mut l = live();
    let n = l.iter().filter(|p| std::fs::remove_file(p).is_ok()).count();
    l.clear();
    n
}

/// The signal that arrived while interrupts were deferred (0: none).
static INTERRUPTED: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(0);
/// Whether the process wants to close its work itself when interrupted ([`defer_interrupts`]).
static DEFERRED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// How long a deferred interrupt waits for the process to close its work before it ends the
/// process anyway (s).
pub const DEFERRED_INTERRUPT_GRACE_S: u64 = 10;

/// Ask for SIGINT/SIGTERM/SIGHUP to be reported instead of ending the process at once: the
/// signal is recorded ([`interrupted`]) for the work to stop at its next safe point and close its
/// records (e.g. the audit trail's run as aborted); the process then ends itself with
/// [`exit_interrupted`]. If it has not within [`DEFERRED_INTERRUPT_GRACE_S`] seconds, the handler
/// removes the temporary files and ends it the default way, as without deferral.
pub fn defer_interrupts() {
    DEFERRED.store(true, std::sync::atomic::Ordering::SeqCst);
    install_signal_cleanup();
}

/// The signal number if the process was interrupted while interrupts were deferred.
pub fn interrupted() -> Option<i32> {
    match INTERRUPTED.load(std::sync::atomic::Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// The name of a signal number (for messages).
pub fn signal_name(sig: i32) -> &'static str {
    match sig {
        2 => "SIGINT",
        15 => "SIGTERM",
        1 => "SIGHUP",
        _ => "a signal",
    }
}

/// End the process after a deferred interrupt: temporary files removed, exit status 128 + the
/// signal number (what a shell reports for a process ended by that signal).
pub fn exit_interrupted(sig: i32) -> ! {
    remove_all_temporaries();
    std::process::exit(128 + sig)
}

fn install_signal_cleanup() {
    HANDLER.call_once(|| {
        #[cfg(unix)]
        {
            use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
            let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
                return;
            };
            let spawned = std::thread::Builder::new().name("truepos-signals".into()).spawn(move || {
                if let Some(sig) = signals.forever().next() {
                    if DEFERRED.load(std::sync::atomic::Ordering::SeqCst) {
                        // The work stops at its next safe point and ends the process itself.
                        INTERRUPTED.store(sig, std::sync::atomic::Ordering::SeqCst);
                        std::thread::sleep(std::time::Duration::from_secs(DEFERRED_INTERRUPT_GRACE_S));
                    }
                    // Hold the registry while removing and ending the process: a commit in
                    // progress finishes its rename first, a new file waits and is never created.
                    let mut l = live();
                    for p in l.iter() {
                        let _ = std::fs::remove_file(p);
                    }
                    l.clear();
                    let _ = signal_hook::low_level::emulate_default_handler(sig);
                    std::process::exit(128 + sig);
                }
            });
            drop(spawned);
        }
    });
}

/// (device, inode, path as given) of every regular file this process opened as an input.
static INPUTS: Mutex<Vec<(u64, u64, PathBuf)>> = Mutex::new(Vec::new());

/// Record `path` as an input of this process (the readers of `truepos-io` call this when they
/// open a file): an output onto the same file (by device and inode) is then refused. Only
/// regular files are recorded.
pub fn note_input(path: &Path) {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let Ok(m) = std::fs::metadata(path) {
            if m.is_file() {
                let mut l = INPUTS.lock().unwrap_or_else(|p| p.into_inner());
                if !l.iter().any(|(d, i, _)| *d == m.dev() && *i == m.ino()) {
                    l.push((m.dev(), m.ino(), path.to_path_buf()));
                }
            }
        }
    }
    #[cfg(not(unix))]
    let _ = path;
}

/// The input (as it was named) that is the same file as `meta`, if any.
#[cfg(unix)]
fn input_named(meta: &std::fs::Metadata) -> Option<PathBuf> {
    use std::os::unix::fs::MetadataExt;
    let mut l = INPUTS.lock().unwrap_or_else(|p| p.into_inner());
    // An input removed since (its inode may now be another file's) is forgotten: the entry
    // counts only while its path still names that device and inode.
    l.retain(|(d, i, p)| std::fs::metadata(p).is_ok_and(|m| m.dev() == *d && m.ino() == *i));
    l.iter().find(|(d, i, _)| *d == meta.dev() && *i == meta.ino()).map(|(_, _, p)| p.clone())
}

#[cfg(not(unix))]
fn input_named(_meta: &std::fs::Metadata) -> Option<PathBuf> {
    None
}

/// What a non-regular file is, for messages.
pub(crate) fn kind_of(ft: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
        if ft.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if ft.is_socket() {
            return "a socket";
        }
    }
    if ft.is_symlink() {
        return "a symbolic link";
    }
    "not a regular file"
}

/// Refuse replacing what is at `path` unless it is a regular file that is not an input.
fn check_replaceable(path: &Path) -> Result<(), OutputError> {
    let Ok(m) = std::fs::symlink_metadata(path) else { return Ok(()) };
    let ft = m.file_type();
    if ft.is_symlink() {
        let to = std::fs::read_link(path).map(|t| format!(" to {}", t.display())).unwrap_or_default();
        return Err(path_error(
            path,
            format!("it is a symbolic link{to}; truepos replaces only regular files (give the link's target as the output)"),
        ));
    }
    if !m.is_file() && !m.is_dir() {
        return Err(path_error(path, format!("it is {}; truepos replaces only regular files", kind_of(&ft))));
    }
    if let Some(input) = input_named(&m) {
        return Err(path_error(
            path,
            format!(
                "it is the same file as the input {}: writing it would destroy the input",
                input.display()
            ),
        ));
    }
    Ok(())
}

/// A path error naming `path`.
fn path_error(path: &Path, message: impl std::fmt::Display) -> OutputError {
    OutputError::Path(InputError::in_file(path, format!("cannot be written as an output: {message}")))
}

/// Check that `path` can become an output file: its directory exists and is a directory, the
/// path is not itself a directory, and what is there now, if anything, is a regular file that
/// is not one of the inputs read so far (see the module's policy).
pub fn check_output_path(path: &Path) -> Result<(), OutputError> {
    if path.as_os_str().is_empty() {
        return Err(OutputError::Path(InputError::new("the output path is empty")));
    }
    if path.is_dir() {
        return Err(path_error(path, "it is a directory"));
    }
    check_replaceable(path)?;
    if path.file_name().is_none() {
        return Err(path_error(path, "it has no file name"));
    }
    let dir = parent_dir(path);
    match std::fs::metadata(&dir) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err(path_error(path, format!("{} is not a directory", dir.display()))),
        Err(_) => Err(path_error(path, format!("the directory {} does not exist", dir.display()))),
    }
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A buffered writer to `<dir>/.<name>.tmp-<pid>-<n>` that becomes `path` on [`commit`](Self::commit).
pub struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    writer: Option<BufWriter<File>>,
    /// Bytes handed to the file by [`write_piece`](Self::write_piece), and how many of them the
    /// kernel was already asked to write back to the disk.
    written: u64,
    writeback_from: u64,
}

/// [`AtomicFile::write_piece`] asks the kernel to start writing back every this many bytes.
const WRITEBACK_BYTES: u64 = 8 << 20;

impl AtomicFile {
    /// Create the temporary file next to `path`. A path that cannot be an output is an
    /// [`OutputError::Path`] naming it.
    pub fn create(path: impl AsRef<Path>) -> Result<Self, OutputError> {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let target = path.as_ref().to_path_buf();
        check_output_path(&target)?;
        install_signal_cleanup();
        let dir = parent_dir(&target);
        let name = target.file_name().unwrap_or_default().to_string_lossy().into_owned();
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let temp = dir.join(format!(".{name}.tmp-{}-{n}", std::process::id()));
        // Registered before it exists, so an interrupt right after creation still removes it.
        let mut l = live();
        l.push(temp.clone());
        let file = match File::create(&temp) {
            Ok(f) => f,
            Err(e) => {
                l.retain(|p| p != &temp);
                return Err(match e.kind() {
                    io::ErrorKind::PermissionDenied | io::ErrorKind::NotFound => {
                        path_error(&target, format!("cannot create a file in {}: {e}", dir.display()))
                    }
                    _ => OutputError::Io { path: target, source: e },
                });
            }
        };
        drop(l);
        Ok(Self {
            target,
            temp,
            writer: Some(BufWriter::with_capacity(1 << 20, file)),
            written: 0,
            writeback_from: 0,
        })
    }

    /// Write `buf` for a large output: a piece of 64 KiB or more goes straight to the file (after
    /// what the buffer holds; no copy into the buffer), a smaller one through the buffer. Every
    /// 8 MiB written (this way or through `Write`) the kernel is asked to start writing the new
    /// bytes back to the disk (`sync_file_range`, Linux), so that the `fsync` of
    /// [`commit`](Self::commit) waits for the last few MiB instead of the whole file, and the disk
    /// works while the caller computes.
    pub fn write_piece(&mut self, buf: &[u8]) -> io::Result<()> {
        let w = self.writer.as_mut().ok_or_else(|| io::Error::other("write after commit"))?;
        if buf.len() >= 64 << 10 {
            w.flush()?;
            w.get_mut().write_all(buf)?;
        } else {
            w.write_all(buf)?;
        }
        self.wrote(buf.len())
    }

    /// Count `n` more bytes written; every [`WRITEBACK_BYTES`], flush the buffer and ask the
    /// kernel to start writing the new bytes back (see [`write_piece`](Self::write_piece)).
    fn wrote(&mut self, n: usize) -> io::Result<()> {
        self.written += n as u64;
        if self.written - self.writeback_from >= WRITEBACK_BYTES {
            if let Some(w) = self.writer.as_mut() {
                w.flush()?;
                let end = self.written;
                start_writeback(w.get_ref(), self.writeback_from, end - self.writeback_from);
                self.writeback_from = end;
            }
        }
        Ok(())
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.target
    }

    /// Flush, sync and rename into place.
    pub fn commit(mut self) -> Result<(), OutputError> {
        let io_err = |source| OutputError::Io { path: self.target.clone(), source };
        if let Some(w) = self.writer.take() {
            let file = match w.into_inner() {
                Ok(f) => f,
                Err(e) => {
                    let _ = std::fs::remove_file(&self.temp);
                    unregister(&self.temp);
                    return Err(io_err(e.into_error()));
                }
            };
            if let Err(e) = file.sync_all() {
                let _ = std::fs::remove_file(&self.temp);
                unregister(&self.temp);
                return Err(io_err(e));
            }
        }
        // Inputs opened since the output was created (a streamed input) are checked again.
        if let Err(e) = check_replaceable(&self.target) {
            let _ = std::fs::remove_file(&self.temp);
            unregister(&self.temp);
            return Err(e);
        }
        // The rename happens with the registry held, so a signal's cleanup runs either before
        // it (the temporary is removed, no output) or after it (a complete output).
        let mut l = live();
        let r = std::fs::rename(&self.temp, &self.target);
        if r.is_err() {
            let _ = std::fs::remove_file(&self.temp);
        }
        l.retain(|p| p != &self.temp);
        r.map_err(io_err)
    }
}

/// Ask the kernel to start writing `len` bytes at `offset` of `file` back to the disk, without
/// waiting. A hint: errors surface at the `fsync` of the commit.
#[cfg(target_os = "linux")]
fn start_writeback(file: &File, offset: u64, len: u64) {
    use std::os::fd::AsRawFd;
    // SAFETY: a plain system call on an open descriptor we own; no memory is passed.
    unsafe {
        libc::sync_file_range(
            file.as_raw_fd(),
            offset as libc::off64_t,
            len as libc::off64_t,
            libc::SYNC_FILE_RANGE_WRITE,
        );
    }
}

#[cfg(not(target_os = "linux"))]
fn start_writeback(_file: &File, _offset: u64, _len: u64) {}

fn unregister(temp: &Path) {
    live().retain(|p| p != temp);
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = match self.writer.as_mut() {
            Some(w) => w.write(buf)?,
            None => return Err(io::Error::other("write after commit")),
        };
        self.wrote(n)?;
        Ok(n)
    }
    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        match self.writer.as_mut() {
            Some(w) => w.write_all(buf)?,
            None => return Err(io::Error::other("write after commit")),
        }
        self.wrote(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        match self.writer.as_mut() {
            Some(w) => w.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let Some(w) = self.writer.take() {
            // Closed before removal; the buffered bytes are discarded with the file.
            drop(w.into_parts());
            let _ = std::fs::remove_file(&self.temp);
            unregister(&self.temp);
        }
    }
}

/// Write `bytes` to `path` atomically.
pub fn write_atomic(path: impl AsRef<Path>, bytes: &[u8]) -> Result<(), OutputError> {
    let mut f = AtomicFile::create(path)?;
    if let Err(source) = f.write_all(bytes) {
        return Err(OutputError::Io { path: f.target.clone(), source });
    }
    f.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_large_and_small_mixed_with_writes_arrive_in_order() {
        // Over 2 × the writeback interval, with pieces on both sides of the 64 KiB cut and plain
        // `write_all`s between them: the committed file is exactly the concatenation.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.bin");
        let mut f = AtomicFile::create(&p).unwrap();
        let mut want = Vec::new();
        let mut k = 0u32;
        while want.len() < 2 * WRITEBACK_BYTES as usize + 12_345 {
            let len = [10, 70_000, 1 << 20, 3, 65_536, 65_535][k as usize % 6];
            let piece: Vec<u8> = (0..len).map(|i| (i as u32 ^ k) as u8).collect();
            if k % 7 == 3 {
                f.write_all(&piece).unwrap();
            } else {
                f.write_piece(&piece).unwrap();
            }
            want.extend_from_slice(&piece);
            k += 1;
        }
        f.commit().unwrap();
        assert!(std::fs::read(&p).unwrap() == want, "content differs");
    }

    #[test]
    fn dropped_file_leaves_nothing_committed_file_appears() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.csv");
        {
            let mut f = AtomicFile::create(&p).unwrap();
            f.write_all(b"partial").unwrap();
            assert!(live().iter().any(|t| t.starts_with(dir.path())));
        }
        assert!(!p.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        assert!(!live().iter().any(|t| t.starts_with(dir.path())));
        write_atomic(&p, b"done").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"done");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        assert!(!live().iter().any(|t| t.starts_with(dir.path())));
    }

    #[test]
    fn bad_output_paths_are_path_errors_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no_such_dir").join("out.csv");
        let e = AtomicFile::create(&missing).err().unwrap();
        assert!(e.is_path());
        assert!(e.to_string().contains("out.csv") && e.to_string().contains("does not exist"), "{e}");
        let e = AtomicFile::create(dir.path()).err().unwrap();
        assert!(e.is_path());
        assert!(e.to_string().contains("directory"), "{e}");
        let file = dir.path().join("f");
        std::fs::write(&file, b"x").unwrap();
        let e = AtomicFile::create(file.join("out.csv")).err().unwrap();
        assert!(e.is_path() && e.to_string().contains("not a directory"), "{e}");
        assert!(write_atomic("", b"x").unwrap_err().is_path());
    }

    /// Only a regular file is replaced: a symlink, a FIFO, a character device are refused
    /// (named), and so is a file that is an input of this process under another name.
    #[cfg(unix)]
    #[test]
    fn only_regular_files_that_are_not_inputs_are_replaced() {
        let d = tempfile::tempdir().unwrap();
        let target = d.path().join("target.csv");
        std::fs::write(&target, b"keep").unwrap();
        let link = d.path().join("link.csv");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let e = write_atomic(&link, b"new").unwrap_err();
        assert!(e.is_path() && e.to_string().contains("symbolic link"), "{e}");
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        let fifo = d.path().join("fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a plain system call with a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = write_atomic(&fifo, b"new").unwrap_err();
        assert!(e.is_path() && e.to_string().contains("FIFO"), "{e}");
        if Path::new("/dev/null").exists() {
            let e = check_output_path(Path::new("/dev/null")).unwrap_err();
            assert!(e.to_string().contains("character device"), "{e}");
        }
        // An input, named another way (a hard link): refused at create, and at commit when the
        // input was opened after the output was created (a streamed input).
        let input = d.path().join("in.csv");
        std::fs::write(&input, b"x_mm\n1\n").unwrap();
        let hard = d.path().join("hard.csv");
        std::fs::hard_link(&input, &hard).unwrap();
        let mut late = AtomicFile::create(&hard).unwrap();
        late.write_all(b"late").unwrap();
        note_input(&d.path().join(".").join("in.csv"));
        let e = write_atomic(&hard, b"new").unwrap_err();
        assert!(e.is_path() && e.to_string().contains("same file as the input"), "{e}");
        let e = late.commit().unwrap_err();
        assert!(e.is_path() && e.to_string().contains("same file as the input"), "{e}");
        assert_eq!(std::fs::read(&input).unwrap(), b"x_mm\n1\n");
        let leftovers: Vec<_> = std::fs::read_dir(d.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
            .collect();
        assert!(leftovers.is_empty());
        // A regular file that is not an input is replaced.
        write_atomic(&target, b"new").unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
    }
}
