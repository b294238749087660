//! Output helpers: a command's outputs appear whole, all together, or not at all.
//!
//! Every output of a command is *staged* in an [`OutputSet`]: written to a hidden temporary file
//! next to its target (`.NAME.tmp-PID-N`, same folder so the final rename is atomic) and synced.
//! [`OutputSet::commit`] then renames every staged file into place, one after the other, with no
//! work in between. Dropping an `OutputSet` without committing it (an error, a panic unwinding)
//! removes its temporary files, and so does SIGINT/SIGTERM once the command line's handler has
//! run ([`abandon_staged_and_exit`]): the process removes every staged temporary file and exits with 130 / 143. A signal that
//! arrives while a commit renames files waits until the commit is done, so the outputs are then
//! complete (and the exit code still says the process was interrupted).
//!
//! Only SIGKILL or a power cut can leave a temporary file, or, during the renames, a partial set;
//! `generate` records a fingerprint of dataset.csv in truth.json so that a truth file beside a
//! dataset it does not describe is detected ([`crate::dataset::truth::TruthFile::find`]).

/// Version of the JSON files twincal writes and reads back (result.json, truth.json,
/// report.json): raised when a field changes meaning or goes away. A file without one was
/// written before versions (0) and is read as version 1.
pub const SCHEMA_VERSION: u32 = 1;

/// [`SCHEMA_VERSION`], for serde's `default`.
pub fn schema_version() -> u32 {
    SCHEMA_VERSION
}

/// Refuses a file of a newer schema than this build reads (`what` names the file's kind).
pub fn check_schema(found: u32, what: &str) -> std::result::Result<(), String> {
    if found > SCHEMA_VERSION {
        return Err(format!("{what} of schema_version {found}, written by a newer twincal; this one reads up to {SCHEMA_VERSION}: update twincal"));
    }
    Ok(())
}

use crate::error::{Error, Result};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError};

/// Temporary files staged by every live [`OutputSet`] of the process. A signal handler removes
/// them; creating and renaming a staged file happen under this lock, so the handler never races
/// a file into existence or half-way through a commit.
static STAGED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn staged_registry() -> MutexGuard<'static, Vec<PathBuf>> {
    STAGED.lock().unwrap_or_else(PoisonError::into_inner)
}

fn unregister(reg: &mut Vec<PathBuf>, tmp: &Path) {
    if let Some(i) = reg.iter().position(|p| p == tmp) {
        reg.swap_remove(i);
    }
}

/// The folder a file path lives in (`.` for a bare file name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `dir/.NAME.tmp-PID-N`: hidden, next to the target, unique per process and per staged file.
fn temp_path_for(target: &Path) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    parent_dir(target).join(format!(".{name}.tmp-{}-{n}", std::process::id()))
}

struct Staged {
    tmp: PathBuf,
    target: PathBuf,
}

/// The outputs of one command, staged as temporary files and renamed into place together by
/// [`commit`](Self::commit). See the [module documentation](self).
#[derive(Default)]
pub struct OutputSet {
    staged: Vec<Staged>,
}

impl OutputSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Creates `target`'s folder and an empty temporary file next to it; returns the open file.
    /// The caller writes the content; [`commit`](Self::commit) renames it into place.
    pub fn stage(&mut self, target: &Path) -> Result<File> {
        if target.file_name().is_none() {
            return Err(Error::Invalid(format!("output path {} does not name a file", target.display())));
        }
        if self.staged.iter().any(|s| s.target == target) {
            return Err(Error::Invalid(format!("output {} is staged twice", target.display())));
        }
        let dir = parent_dir(target);
        std::fs::create_dir_all(&dir).map_err(|e| Error::create_dir(&dir, e))?;
        let tmp = temp_path_for(target);
        let file = {
            let mut reg = staged_registry();
            let f = OpenOptions::new().write(true).create_new(true).open(&tmp).map_err(|e| Error::write(target, e))?;
            reg.push(tmp.clone());
            f
        };
        self.staged.push(Staged { tmp, target: target.to_path_buf() });
        Ok(file)
    }

    /// Stages `bytes` as the content of `target` (written and synced now, renamed by `commit`).
    pub fn write(&mut self, target: &Path, bytes: &[u8]) -> Result<()> {
        let mut f = self.stage(target)?;
        f.write_all(bytes).and_then(|()| f.sync_all()).map_err(|e| Error::write(target, e))
    }

    /// Stages `value` as pretty JSON.
    pub fn write_json<T: serde::Serialize>(&mut self, target: &Path, value: &T) -> Result<()> {
        let s = serde_json::to_string_pretty(value).map_err(|e| Error::Invalid(format!("cannot serialise {}: {e}", target.display())))?;
        self.write(target, s.as_bytes())
    }

    /// Renames every staged file into place, in staging order. A rename that fails stops the
    /// commit with an error; the files not yet renamed are removed.
    pub fn commit(mut self) -> Result<()> {
        // A stop asked for (Ctrl-C) after the work's last check: nothing is put in place (the
        // staged files go with the unwinding set).
        crate::progress::check_stop();
        let mut reg = staged_registry();
        while !self.staged.is_empty() {
            let s = &self.staged[0];
            if let Err(e) = std::fs::rename(&s.tmp, &s.target) {
                return Err(Error::write(&s.target, e));
            }
            unregister(&mut reg, &s.tmp);
            self.staged.remove(0);
        }
        Ok(())
    }

    /// Temporary paths currently staged (for tests and diagnostics).
    pub fn temp_paths(&self) -> Vec<PathBuf> {
        self.staged.iter().map(|s| s.tmp.clone()).collect()
    }
}

impl Drop for OutputSet {
    /// Not committed (error, panic): remove every temporary file, leave the targets untouched.
    fn drop(&mut self) {
        if self.staged.is_empty() {
            return;
        }
        let mut reg = staged_registry();
        for s in self.staged.drain(..) {
            let _ = std::fs::remove_file(&s.tmp);
            unregister(&mut reg, &s.tmp);
        }
    }
}

/// Writes `bytes` to `path` whole or not at all (a one-file [`OutputSet`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut set = OutputSet::new();
    set.write(path, bytes)?;
    set.commit()
}

/// Serialises `value` as pretty JSON and writes it whole or not at all.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<()> {
    let mut set = OutputSet::new();
    set.write_json(path, value)?;
    set.commit()
}

/// Removes every staged temporary file and ends the process with `code`, after printing
/// `message` on stderr. The registry stays locked until the exit, so no file can be staged or
/// renamed after the removal; a commit in progress finishes first. For a signal handler (the
/// command line's SIGINT / SIGTERM handler calls it with 128 + the signal number).
pub fn abandon_staged_and_exit(message: &str, code: i32) -> ! {
    let reg = staged_registry();
    for p in reg.iter() {
        let _ = std::fs::remove_file(p);
    }
    eprintln!("{message}");
    std::process::exit(code)
}

thread_local! {
    /// Set while [`catch_quietly`] runs its closure on this thread.
    static QUIET_PANICS: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f`, turning a panic inside it into `Err(message)`; the panic prints nothing when the
/// process's panic hook consults [`panics_are_quiet`] (the command line's does). For third-party
/// code that panics on malformed input (the spreadsheet reader), where the caller has its own
/// clean error to give.
pub fn catch_quietly<T>(f: impl FnOnce() -> T) -> std::result::Result<T, String> {
    let before = QUIET_PANICS.with(|q| q.replace(true));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    QUIET_PANICS.with(|q| q.set(before));
    r.map_err(|panic| {
        panic.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| panic.downcast_ref::<String>().cloned()).unwrap_or_else(|| "unknown failure".into())
    })
}

/// Whether a panic on this thread happens inside [`catch_quietly`] (a panic hook then stays silent).
pub fn panics_are_quiet() -> bool {
    QUIET_PANICS.with(|q| q.get())
}

/// `path` made absolute with symbolic links resolved, also when it does not exist yet: its
/// deepest existing ancestor is canonicalised and the remaining components appended.
pub fn canonical(path: &Path) -> PathBuf {
    let abs = if path.is_absolute() { path.to_path_buf() } else { std::env::current_dir().map(|d| d.join(path)).unwrap_or_else(|_| path.to_path_buf()) };
    let mut rest = Vec::new();
    let mut cur = abs.as_path();
    loop {
        if let Ok(c) = cur.canonicalize() {
            let mut out = c;
            for part in rest.iter().rev() {
                out.push(part);
            }
            return out;
        }
        match (cur.parent(), cur.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_owned());
                cur = parent;
            }
            _ => return abs,
        }
    }
}

/// A command-line path with the option that named it, for messages ("--out result.json").
pub type Named<'a> = (&'a str, &'a Path);

/// Refuses outputs that would destroy an input or each other: an output that is also an input,
/// two outputs on the same file, or an output that is an existing folder. Paths are compared
/// canonicalised ([`canonical`]), so `./d/../d/x.csv` and a symbolic link are caught too.
/// The inputs are named paths, borrowed or owned.
pub fn check_outputs<P: AsRef<Path>>(inputs: &[(&str, P)], outputs: &[Named]) -> Result<()> {
    let ins: Vec<(&str, &Path, PathBuf)> = inputs.iter().map(|(o, p)| (*o, p.as_ref(), canonical(p.as_ref()))).collect();
    let mut seen: Vec<(&str, &Path, PathBuf)> = Vec::new();
    for (opt, p) in outputs {
        let c = canonical(p);
        if let Some((iopt, ip, _)) = ins.iter().find(|(_, _, ic)| *ic == c) {
            return Err(Error::Invalid(format!("output {} ({opt}) is also an input ({iopt} {}): refusing to overwrite it", p.display(), ip.display())));
        }
        if let Some((sopt, sp, _)) = seen.iter().find(|(_, _, sc)| *sc == c) {
            return Err(Error::Invalid(format!("outputs {opt} {} and {sopt} {} are the same file", p.display(), sp.display())));
        }
        if c.is_dir() {
            return Err(Error::Invalid(format!("output {} ({opt}) is an existing folder, not a file", p.display())));
        }
        // An output is renamed into place: over a device, a pipe or a link that would replace
        // the special file itself (/dev/null, /dev/stdout, a FIFO, a symlink), not write to it.
        if let Ok(m) = std::fs::symlink_metadata(p) {
            if !m.file_type().is_file() {
                let what = if m.file_type().is_symlink() { "a symbolic link" } else { "not a regular file (a device, pipe or socket)" };
                return Err(Error::Invalid(format!(
                    "output {} ({opt}) is {what}: twincal writes a new file and renames it into place, which would replace it; name a regular file",
                    p.display()
                )));
            }
        }
        seen.push((opt, p, c));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    #[test]
    fn staged_outputs_appear_together_on_commit() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("sub/a.csv");
        let b = dir.path().join("b.json");
        std::fs::write(&b, "old").unwrap();
        let mut set = OutputSet::new();
        set.write(&a, b"x,y\n").unwrap();
        set.write_json(&b, &serde_json::json!({"k": 1})).unwrap();
        assert!(!a.exists(), "nothing appears before commit");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "old");
        let tmps = set.temp_paths();
        assert_eq!(tmps.len(), 2);
        assert!(tmps.iter().all(|t| t.exists() && staged_registry().contains(t)));
        set.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "x,y\n");
        assert!(std::fs::read_to_string(&b).unwrap().contains("\"k\": 1"));
        assert_eq!(names(dir.path()), vec!["b.json", "sub"]);
        assert_eq!(names(&dir.path().join("sub")), vec!["a.csv"]);
        assert!(tmps.iter().all(|t| !staged_registry().contains(t)));
    }

    #[test]
    fn dropped_set_leaves_nothing_and_keeps_old_targets() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.csv");
        std::fs::write(&a, "old").unwrap();
        let tmps = {
            let mut set = OutputSet::new();
            set.write(&a, b"new").unwrap();
            set.write(&dir.path().join("b.rrd"), b"rec").unwrap();
            set.temp_paths()
        };
        assert_eq!(names(dir.path()), vec!["a.csv"]);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
        assert!(tmps.iter().all(|t| !staged_registry().contains(t)));
    }

    #[test]
    fn failed_commit_removes_the_rest() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.csv");
        let b = dir.path().join("b.csv");
        let mut set = OutputSet::new();
        set.write(&a, b"1").unwrap();
        set.write(&b, b"2").unwrap();
        // The target became a non-empty folder after staging: its rename fails.
        std::fs::create_dir(&a).unwrap();
        std::fs::write(a.join("keep"), "x").unwrap();
        let e = set.commit().unwrap_err().to_string();
        assert!(e.starts_with(&format!("cannot write {}", a.display())), "{e}");
        assert_eq!(names(dir.path()), vec!["a.csv"]);
    }

    #[test]
    fn write_errors_say_write_and_folder_errors_say_folder() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("file");
        std::fs::write(&blocker, "x").unwrap();
        let e = write_atomic(&blocker.join("x.csv"), b"1").unwrap_err().to_string();
        assert!(e.starts_with(&format!("cannot create folder {}", blocker.display())), "{e}");
        assert_eq!(names(dir.path()), vec!["file"]);
    }

    #[test]
    fn outputs_onto_inputs_or_each_other_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let data = dir.path().join("d.csv");
        std::fs::write(&data, "x").unwrap();
        let sub = dir.path().join("sub");
        std::fs::create_dir(&sub).unwrap();
        // Same file reached through `..`, and a not-yet-existing output in an existing folder.
        let again = sub.join("../d.csv");
        let e = check_outputs(&[("--data", &data)], &[("--out", &again)]).unwrap_err().to_string();
        assert!(e.contains("is also an input") && e.contains("--data"), "{e}");
        let x = dir.path().join("new/x.json");
        let x2 = dir.path().join("new/./x.json");
        let e = check_outputs(&[("--data", &data)], &[("--out", &x), ("--urdf", &x2)]).unwrap_err().to_string();
        assert!(e.contains("are the same file"), "{e}");
        let e = check_outputs::<&Path>(&[], &[("--out", &sub)]).unwrap_err().to_string();
        assert!(e.contains("existing folder"), "{e}");
        check_outputs(&[("--data", &data)], &[("--out", &x), ("--rrd", &dir.path().join("r.rrd"))]).unwrap();
        #[cfg(unix)]
        {
            let link = dir.path().join("link.csv");
            std::os::unix::fs::symlink(&data, &link).unwrap();
            assert!(check_outputs(&[("--data", &data)], &[("--out", &link)]).is_err());
        }
    }
}
