//! Atomic file output: write to a temporary sibling, then rename, so that an interrupted run
//! never leaves a half-written file that looks complete.
use crate::error::{CoreError, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The temporary sibling used while `path` is being written (same folder, so rename is atomic).
pub fn temp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    // pid + a process-wide counter: concurrent writers (threads or processes) never share a temp.
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = format!(".{name}.{}.{n}.tmp", std::process::id());
    path.with_file_name(tmp)
}

/// Write `path` by calling `write` on a temporary path and renaming it on success.
/// On failure the temporary file is removed and `path` is left untouched.
pub fn write_atomic_with<T>(path: &Path, write: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
    if let Some(parent) = path.parent() {
        if !parent.as_os_str().is_empty() {
            std::fs::create_dir_all(parent).map_err(|e| CoreError::io(parent, e))?;
        }
    }
    let tmp = temp_path(path);
    match write(&tmp) {
        Ok(v) => {
            std::fs::rename(&tmp, path).map_err(|e| CoreError::io(path, e))?;
            Ok(v)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Write `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |tmp| {
        let mut f = std::fs::File::create(tmp).map_err(|e| CoreError::io(tmp, e))?;
        f.write_all(bytes).map_err(|e| CoreError::io(tmp, e))?;
        f.sync_all().map_err(|e| CoreError::io(tmp, e))?;
        Ok(())
    })
}

/// True when `name` is a temporary of [`temp_path`]'s pattern: `.<name>.<pid>.<n>.tmp`.
pub fn is_temp_name(name: &str) -> bool {
    let Some(inner) = name.strip_prefix('.').and_then(|n| n.strip_suffix(".tmp")) else { return false };
    let mut parts = inner.rsplitn(3, '.');
    let (Some(n), Some(pid), Some(base)) = (parts.next(), parts.next(), parts.next()) else { return false };
    !base.is_empty()
        && !n.is_empty()
        && !pid.is_empty()
        && n.bytes().all(|b| b.is_ascii_digit())
        && pid.bytes().all(|b| b.is_ascii_digit())
}

/// Remove the temporaries left by interrupted writers (names of [`temp_path`]'s pattern) under
/// `dir`, recursively, skipping those of the current process. Returns how many were removed.
/// Call it at the start of a resumed run, before any worker starts writing.
pub fn remove_stale_temps(dir: &Path) -> Result<usize> {
    let own = format!(".{}.", std::process::id());
    let mut removed = 0;
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else { continue };
        for e in rd.flatten() {
            let Ok(ft) = e.file_type() else { continue };
            let p = e.path();
            if ft.is_dir() {
                stack.push(p);
            } else if ft.is_file() {
                let name = e.file_name().to_string_lossy().into_owned();
                if is_temp_name(&name) && !name.contains(&own) {
                    std::fs::remove_file(&p).map_err(|e| CoreError::io(&p, e))?;
                    removed += 1;
                }
            }
        }
    }
    Ok(removed)
}

/// Refuse an output that would overwrite (or, for a folder, be or lie inside) an input:
/// `output` is a file or folder about to be written, `inputs` the files or folders read.
/// Paths are compared after resolving symbolic links and `..` (of their existing part); a file
/// output is also refused when it is a hard link to an input (same device and inode), since
/// writing it would replace the input's content under another name. The error names both.
///
/// A folder output only checks the folder: call [`refuse_overwrite_in`] (or this function with
/// `output_is_dir = false`) for every file the command writes into it.
pub fn refuse_overwrite(output: &Path, inputs: &[&Path], output_is_dir: bool) -> Result<()> {
    let out = resolve(output);
    for &i in inputs {
        let inp = resolve(i);
        let clash = if output_is_dir {
            // Writing into a folder that is (or lies inside) an input folder: outputs would
            // replace inputs of the same relative name, or be read back as inputs.
            out == inp || (i.is_dir() && out.starts_with(&inp))
        } else {
            out == inp
        };
        if clash {
            return Err(CoreError::invalid(
                "output",
                format!("{} would overwrite the input {}; choose another output", output.display(), i.display()),
            ));
        }
        if !output_is_dir && same_file(output, i) {
            return Err(CoreError::invalid(
                "output",
                format!(
                    "{} is a hard link to the input {} (the same file): writing it would change the input; \
                     choose another output",
                    output.display(),
                    i.display()
                ),
            ));
        }
    }
    Ok(())
}

/// [`refuse_overwrite`] for a command that writes the files `names` into the folder `dir`: the
/// folder itself, then every file `dir/name`, against every input. Also refuses two outputs
/// that are the same file (a name given twice).
pub fn refuse_overwrite_in(dir: &Path, names: &[&str], inputs: &[&Path]) -> Result<()> {
    refuse_overwrite(dir, inputs, true)?;
    let files: Vec<PathBuf> = names.iter().map(|n| dir.join(n)).collect();
    let refs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    refuse_overwrite_files(&refs, inputs)
}

/// [`refuse_overwrite`] for every file in `outputs` (files, not folders), and refuses two outputs
/// that resolve to the same file (the second would replace the first).
pub fn refuse_overwrite_files(outputs: &[&Path], inputs: &[&Path]) -> Result<()> {
    for (k, &o) in outputs.iter().enumerate() {
        refuse_overwrite(o, inputs, false)?;
        if let Some(&prev) = outputs[..k].iter().find(|&&p| resolve(p) == resolve(o) || same_file(p, o)) {
            return Err(CoreError::invalid(
                "output",
                format!("{} and {} are the same file: choose two different outputs", prev.display(), o.display()),
            ));
        }
    }
    Ok(())
}

/// True when `a` and `b` both exist and are the same file: same device and inode on unix (hard
/// links, bind mounts), the same resolved path elsewhere.
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (std::fs::metadata(a), std::fs::metadata(b)) {
            (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        a.exists() && b.exists() && resolve(a) == resolve(b)
    }
}

/// Absolute, symlink-free form of `p`: the longest existing ancestor is canonicalised and the
/// rest appended (so that a not-yet-created output compares equal to what it will be).
pub fn resolve(p: &Path) -> PathBuf {
    let abs = if p.is_absolute() {
        p.to_path_buf()
    } else {
        std::env::current_dir().map(|c| c.join(p)).unwrap_or_else(|_| p.to_path_buf())
    };
    let mut tail = Vec::new();
    let mut cur = abs.as_path();
    loop {
        if let Ok(c) = std::fs::canonicalize(cur) {
            let mut out = c;
            for t in tail.iter().rev() {
                out.push(t);
            }
            return normalize(&out);
        }
        match (cur.parent(), cur.file_name()) {
            (Some(parent), Some(name)) => {
                tail.push(name.to_os_string());
                cur = parent;
            }
            _ => return normalize(&abs),
        }
    }
}

/// Lexical removal of `.` and `..` components.
fn normalize(p: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// Stable 64-bit FNV-1a hash of `bytes` as 16 hex digits: the parameter hash stored in resume
/// sidecars (stable across Rust versions and platforms, unlike `DefaultHasher`).
pub fn fnv1a64_hex(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.bin");
        let r: Result<()> = write_atomic_with(&p, |tmp| {
            std::fs::write(tmp, b"partial").unwrap();
            Err(CoreError::invalid("test", "fail"))
        });
        assert!(r.is_err());
        assert!(!p.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        write_atomic(&p, b"ok").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"ok");
    }

    #[test]
    fn stale_temporaries_are_recognised_and_removed() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("a/b");
        std::fs::create_dir_all(&sub).unwrap();
        let stale = sub.join(".x.png.999999999.3.tmp");
        std::fs::write(&stale, b"half").unwrap();
        // Not ours: other hidden files and our own process' live temporaries.
        let keep = [sub.join(".hidden.tmp"), sub.join("x.png"), dir.path().join(".cfg")];
        for k in &keep {
            std::fs::write(k, b"k").unwrap();
        }
        let live = temp_path(&sub.join("y.png"));
        std::fs::write(&live, b"live").unwrap();
        assert!(is_temp_name(".x.png.999999999.3.tmp"));
        assert!(!is_temp_name(".hidden.tmp") && !is_temp_name(".a.b.tmp") && !is_temp_name("x.1.2.tmp"));
        assert_eq!(remove_stale_temps(dir.path()).unwrap(), 1);
        assert!(!stale.exists() && live.exists());
        assert!(keep.iter().all(|k| k.exists()));
    }

    #[test]
    fn outputs_that_overwrite_inputs_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let inp = d.join("in.toml");
        std::fs::write(&inp, b"x").unwrap();
        let err = refuse_overwrite(&d.join("./sub/../in.toml"), &[&inp], false).unwrap_err().to_string();
        assert!(err.contains("in.toml") && err.contains("overwrite"), "{err}");
        assert!(refuse_overwrite(&d.join("out.toml"), &[&inp], false).is_ok());
        // Folders: the same folder or a folder inside the input folder.
        let data = d.join("data");
        std::fs::create_dir_all(data.join("left")).unwrap();
        assert!(refuse_overwrite(&data, &[&data], true).is_err());
        assert!(refuse_overwrite(&data.join("aug"), &[&data], true).is_err());
        assert!(refuse_overwrite(&d.join("aug"), &[&data], true).is_ok());
        assert_eq!(fnv1a64_hex(b""), "cbf29ce484222325");
        // A file written into the output folder that is an input (`--out .` next to the input).
        let err = refuse_overwrite_in(d, &["report.json", "in.toml"], &[&inp]).unwrap_err().to_string();
        assert!(err.contains("in.toml") && err.contains("overwrite"), "{err}");
        assert!(refuse_overwrite_in(d, &["report.json"], &[&inp]).is_ok());
        // Two outputs that are the same file.
        let err = refuse_overwrite_files(&[&d.join("a.json"), &d.join("x/../a.json")], &[&inp]).unwrap_err();
        assert!(err.to_string().contains("same file"), "{err}");
        assert_eq!(fnv1a64_hex(b"a"), "af63dc4c8601ec8c");
    }

    #[cfg(unix)]
    #[test]
    fn hard_links_to_inputs_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("liver.obj");
        std::fs::write(&inp, b"v 0 0 0").unwrap();
        let link = dir.path().join("out").join("landmarks.json");
        std::fs::create_dir_all(link.parent().unwrap()).unwrap();
        std::fs::hard_link(&inp, &link).unwrap();
        let err = refuse_overwrite(&link, &[&inp], false).unwrap_err().to_string();
        assert!(err.contains("hard link") && err.contains("liver.obj") && err.contains("landmarks.json"), "{err}");
        let err = refuse_overwrite_in(&dir.path().join("out"), &["landmarks.json"], &[&inp]).unwrap_err();
        assert!(err.to_string().contains("hard link"), "{err}");
        assert!(same_file(&inp, &link) && !same_file(&inp, &dir.path().join("absent")));
        let other = dir.path().join("copy.obj");
        std::fs::copy(&inp, &other).unwrap();
        assert!(refuse_overwrite(&other, &[&inp], false).is_ok());
    }
}
