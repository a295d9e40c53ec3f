//! What the tests that run `guide-sim` as a process share: starting it and
//! waiting for its ready line, and killing it (with whatever it started)
//! when the test ends, however it ends.

use std::io::{BufRead, BufReader};
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

/// A process group we started (its leader and what it started), killed on
/// drop.
pub struct Group(pub Child);

impl Drop for Group {
    fn drop(&mut self) {
        // SAFETY: kill(2) on the process group of our own child (it leads
        // it: started with process_group(0)).
        unsafe { libc::kill(-(self.0.id() as libc::pid_t), libc::SIGKILL) };
        let _ = self.0.wait();
    }
}

/// Starts `guide-sim args` and waits (at most 20 s) for its ready line.
pub fn guide_sim(args: &[&str]) -> (Group, String) {
    guide_sim_with(args, Stdio::inherit())
}

/// As [`guide_sim`], its stderr sent to `stderr` (piped: `group.0.stderr`).
pub fn guide_sim_with(args: &[&str], stderr: Stdio) -> (Group, String) {
    let mut g = Group(
        Command::new(env!("CARGO_BIN_EXE_guide-sim"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(stderr)
            .process_group(0)
            .spawn()
            .expect("guide-sim runs"),
    );
    let stdout = g.0.stdout.take().expect("piped stdout");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = BufReader::new(stdout).read_line(&mut line);
        let _ = tx.send(line);
    });
    let line = rx
        .recv_timeout(Duration::from_secs(20))
        .unwrap_or_else(|_| panic!("guide-sim {args:?}: no ready line within 20 s"));
    (g, line)
}
