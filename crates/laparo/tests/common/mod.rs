//! Helpers shared by the CLI tests: run the `laparo` binary and write small inputs.
#![allow(dead_code)]
use std::path::Path;
use std::process::{Command, Output};

/// Run `laparo args` in `cwd`: (success, stdout, stderr).
pub fn laparo(args: &[&str], cwd: &Path) -> (bool, String, String) {
    let o = run(args, cwd);
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Run `laparo args` in `cwd` and return the raw output.
pub fn run(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_laparo")).args(args).current_dir(cwd).output().expect("run laparo")
}

/// Run `laparo args` in `cwd`, killed after `secs` seconds: (success, stderr); a hang fails the test.
pub fn laparo_within(args: &[&str], cwd: &Path, secs: u64) -> (bool, String) {
    use std::io::Read;
    let mut child = Command::new(env!("CARGO_BIN_EXE_laparo"))
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
