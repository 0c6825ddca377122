//! `laparo … | head -1`: a reader that leaves early ends the command quietly (issue 49) — no panic,
//! no backtrace, exit 0 or death by SIGPIPE (the shell's 141), never 101.
mod common;
use common::{command, write_texture_png};
use std::path::Path;
use std::process::Stdio;

/// Run `args` in `cwd` with stdout a pipe whose reader is already closed: every write fails with EPIPE.
fn closed_stdout(args: &[&str], cwd: &Path) {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = command().args(args).current_dir(cwd).stdout(Stdio::from(writer)).stderr(Stdio::piped()).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    #[cfg(unix)]
    let by_sigpipe = std::os::unix::process::ExitStatusExt::signal(&o.status) == Some(SIGPIPE);
    #[cfg(not(unix))]
    let by_sigpipe = false;
    assert!(o.status.success() || by_sigpipe, "{args:?}: {:?}\n{err}", o.status);
    assert!(!err.contains("panicked") && !err.contains("Broken pipe"), "{args:?}: {err}");
}

/// SIGPIPE on Linux and macOS.
#[cfg(unix)]
const SIGPIPE: i32 = 13;

#[test]
fn a_closed_stdout_ends_printing_commands_quietly() {
    let dir = tempfile::tempdir().unwrap();
    write_texture_png(&dir.path().join("i.png"), 64, 64, 7);
    write_texture_png(&dir.path().join("j.png"), 64, 64, 8);
    closed_stdout(&["features", "detect", "--image", "i.png", "--out", "k.json"], dir.path());
    closed_stdout(&["features", "match", "--image1", "i.png", "--image2", "j.png", "--out", "m"], dir.path());
    std::fs::write(
        dir.path().join("t.vtk"),
        "# vtk DataFile Version 2.0\ntet\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n\
         0 0 0\n10 0 0\n0 10 0\n0 0 10\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("fixed.json"), r#"{"vertices": [0, 1, 2]}"#).unwrap();
    std::fs::write(dir.path().join("loads.json"), r#"{"nodal_forces": [{"vertex": 3, "force_mn": [0, 0, 1]}]}"#)
        .unwrap();
    let fem = ["fem", "solve", "--mesh", "t.vtk", "--fixed", "fixed.json", "--loads", "loads.json", "--out", "f"];
    closed_stdout(&fem, dir.path());
    closed_stdout(&["--help"], dir.path());
}
