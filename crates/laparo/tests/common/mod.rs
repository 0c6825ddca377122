//! Helpers shared by the CLI tests: run the `laparo` binary, check JSON outputs, write small inputs.
//! Every CLI test runs the binary through these (one place for how it is found and run).
#![allow(dead_code)]
use std::path::Path;
use std::process::{Command, Output};

/// The built `laparo` binary.
pub const BIN: &str = env!("CARGO_BIN_EXE_laparo");

/// The `laparo` command, for tests that add path arguments, stdin, pipes or environment variables.
pub fn command() -> Command {
    Command::new(BIN)
}

/// Run `laparo args` and return the raw output (status and bytes).
pub fn run(args: &[&str]) -> Output {
    command().args(args).output().expect("run laparo")
}

/// [`run`] in `cwd`.
pub fn run_in(args: &[&str], cwd: &Path) -> Output {
    command().args(args).current_dir(cwd).output().expect("run laparo")
}

/// Run `laparo args`: (success, stdout, stderr).
pub fn laparo(args: &[&str]) -> (bool, String, String) {
    texts(run(args))
}

/// [`laparo`] in `cwd`.
pub fn laparo_in(args: &[&str], cwd: &Path) -> (bool, String, String) {
    texts(run_in(args, cwd))
}

/// Run `laparo args`, which must succeed (the failure quotes stderr); its stdout.
pub fn laparo_ok(args: &[&str]) -> String {
    let (ok, out, err) = laparo(args);
    assert!(ok, "laparo {args:?}: {err}");
    out
}

fn texts(o: Output) -> (bool, String, String) {
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The paths (from `path`) of the bare `null`s in `v`. A figure that is missing says why: a `null`
/// field needs a sibling `<key>_reason` string, and a `null` inside an array is as bare as a field
/// `null` unless the array's key has a `<key>_reason` beside it (array elements have no siblings of
/// their own; the reason covers the array's direct elements).
pub fn bare_nulls(v: &serde_json::Value, path: &str) -> Vec<String> {
    fn walk(v: &serde_json::Value, path: &str, out: &mut Vec<String>) {
        match v {
            serde_json::Value::Object(m) => {
                for (k, x) in m {
                    let explained = m.get(&format!("{k}_reason")).is_some_and(|r| r.is_string());
                    let p = format!("{path}.{k}");
                    match x {
                        serde_json::Value::Null if !explained => out.push(p),
                        serde_json::Value::Array(a) => elements(a, &p, explained, out),
                        _ => walk(x, &p, out),
                    }
                }
            }
            serde_json::Value::Array(a) => elements(a, path, false, out),
            _ => {}
        }
    }
    fn elements(a: &[serde_json::Value], path: &str, explained: bool, out: &mut Vec<String>) {
        for (i, x) in a.iter().enumerate() {
            let p = format!("{path}[{i}]");
            match x {
                serde_json::Value::Null if !explained => out.push(p),
                _ => walk(x, &p, out),
            }
        }
    }
    let mut out = Vec::new();
    walk(v, path, &mut out);
    out
}

/// Run `laparo args` in `cwd`, killed after `secs` seconds: (success, stderr); a hang fails the test.
pub fn laparo_within(args: &[&str], cwd: &Path, secs: u64) -> (bool, String) {
    use std::io::Read;
    let mut child = command()
        .args(args)
        .current_dir(cwd)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run laparo");
    // stderr is drained while the command runs: a full pipe must not block it.
    let mut pipe = child.stderr.take().expect("piped");
    let reader = std::thread::spawn(move || {
        let mut err = String::new();
        let _ = pipe.read_to_string(&mut err);
        err
    });
    let t0 = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break s;
        }
        if t0.elapsed().as_secs() >= secs {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{args:?} still running after {secs} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    (status.success(), reader.join().expect("stderr reader"))
}

/// A `w`×`h` grey PNG with a seeded texture (enough corners for SIFT/ORB).
pub fn write_texture_png(path: &Path, w: usize, h: usize, seed: u64) {
    let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    let mut cells = vec![0u8; 64];
    for c in &mut cells {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *c = (s >> 56) as u8;
    }
    let data: Vec<u8> = (0..w * h).map(|k| cells[((k % w) / 8 % 8) + 8 * ((k / w) / 8 % 8)]).collect();
    let img = laparo_core::image::Image::from_vec(w, h, 1, data).expect("image");
    laparo_core::io::write_png(path, &img).expect("write png");
}
