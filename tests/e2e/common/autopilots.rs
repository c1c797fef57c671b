//! Simulated autopilots for the tests that fly aircraft (`examples/python/sim_autopilot.py`, real
//! MAVLink 2 through pymavlink, one process per UAV of `scenarios/geo.toml`).

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use super::{kill, python};

/// The nominal scenario placed at an origin.
pub const GEO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/geo.toml");
pub const ORIGIN: &str = "47.3977,8.5456,488";
pub const STARTS: [&str; 3] = ["1500,500", "10000,1500", "5000,8500"];
/// Simulated seconds per wall second: the paper's 10 s step in 0.5 s.
pub const TIME_SCALE: &str = "20";

/// UDP ports of this test process (one block per process, so parallel test binaries never share one).
pub fn ports(block: u16) -> [u16; 3] {
    let base = 20_000 + (std::process::id() % 2_000) as u16 * 16 + block * 4;
    [base, base + 1, base + 2]
}

/// The simulated autopilots of one test, killed when dropped.
pub struct Autopilots(Vec<Child>);

impl Autopilots {
    /// One autopilot per UAV, sending to `ports` on loopback; `extra[i]` are UAV i's own flags.
    pub fn start(ports: [u16; 3], extra: [&[&str]; 3], dir: &Path) -> Self {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/python/sim_autopilot.py");
        let py = python();
        Self(
            (0..3)
                .map(|i| {
                    Command::new(&py)
                        .arg(&script)
                        .args(["--connect", &format!("udpout:127.0.0.1:{}", ports[i])])
                        .args(["--system-id", &(i + 1).to_string(), "--origin", ORIGIN, "--start", STARTS[i]])
                        .args(["--time-scale", TIME_SCALE, "--duration", "120"])
                        .args(extra[i])
                        .stdout(std::fs::File::create(dir.join(format!("autopilot{i}.out"))).unwrap())
                        .stderr(std::fs::File::create(dir.join(format!("autopilot{i}.err"))).unwrap())
                        .stdin(Stdio::null())
                        .spawn()
                        .expect("start a simulated autopilot")
                })
                .collect(),
        )
    }
}

impl Drop for Autopilots {
    /// SIGTERM (each prints its report), then SIGKILL for one that does not end within 5 s.
    fn drop(&mut self) {
        for c in &self.0 {
            kill(c.id(), libc::SIGTERM);
        }
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        for c in &mut self.0 {
            while c.try_wait().ok().flatten().is_none() && std::time::Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(10));
            }
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

pub fn endpoints(ports: [u16; 3]) -> Vec<String> {
    ports.iter().flat_map(|p| ["--autopilot".to_string(), format!("udpin:127.0.0.1:{p}")]).collect()
}
