//! Linux process helpers of `uavloc bench`: CPU affinity (which cores the benchmark runs on), the CPU
//! time and resident memory of a process from `/proc`, and waiting for a child's exit without reaping it
//! (so that its CPU time can still be read).
//!
//! Affinity masks are `cpu_set_t`s, so cores are numbered 0 .. 1023 (`CPU_SETSIZE`); on a machine with
//! more CPUs `sched_getaffinity` fails and so do [`allowed_cores`] and [`parse_cores`].

use std::io;
use std::mem::MaybeUninit;

/// The machine a benchmark ran on, as every `uavloc bench` report gives it (JSON `cpus`, `cpu_model`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Machine {
    /// Online CPUs (`sysconf(_SC_NPROCESSORS_ONLN)`: the machine's, whatever cores the benchmark is
    /// pinned to).
    pub cpus: usize,
    /// The CPU model (`/proc/cpuinfo`), when known.
    pub cpu_model: Option<String>,
}

impl Machine {
    /// This machine.
    pub fn this() -> Self {
        let online = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) };
        let cpus =
            if online >= 1 { online as usize } else { std::thread::available_parallelism().map_or(1, |n| n.get()) };
        Self { cpus, cpu_model: cpu_model() }
    }

    /// `2 online CPU(s), <model>`.
    pub fn describe(&self) -> String {
        format!("{} online CPU(s){}", self.cpus, self.cpu_model.as_ref().map_or(String::new(), |m| format!(", {m}")))
    }
}

/// The CPU model of the first processor in `/proc/cpuinfo`.
fn cpu_model() -> Option<String> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    info.lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map(|(_, v)| v.trim().to_string())
        .filter(|v| !v.is_empty())
}

/// The cores of a `cpu_set_t` (0 .. `CPU_SETSIZE`).
fn set_cores(set: &libc::cpu_set_t) -> Vec<usize> {
    (0..libc::CPU_SETSIZE as usize).filter(|&c| unsafe { libc::CPU_ISSET(c, set) }).collect()
}

/// Number of CPUs configured on this machine (`sysconf(_SC_NPROCESSORS_CONF)`).
fn configured_cpus() -> Result<usize, String> {
    let n = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_CONF) };
    if n < 1 {
        Err(format!("cannot read the number of configured CPUs: {}", io::Error::last_os_error()))
    } else {
        Ok(n as usize)
    }
}

/// The value of `sysconf(name)` (`what` names it in the error), which must be positive.
fn sysconf_positive(name: libc::c_int, what: &str) -> Result<u64, String> {
    let v = unsafe { libc::sysconf(name) };
    if v < 1 { Err(format!("cannot read {what}: {}", io::Error::last_os_error())) } else { Ok(v as u64) }
}

/// The cores the calling thread may run on (`sched_getaffinity(0)`; for a single-threaded process, or
/// the thread that spawns the children, that is the process's set), ascending.
pub fn allowed_cores() -> Result<Vec<usize>, String> {
    let mut set = MaybeUninit::<libc::cpu_set_t>::zeroed();
    let rc = unsafe { libc::sched_getaffinity(0, size_of::<libc::cpu_set_t>(), set.as_mut_ptr()) };
    if rc != 0 {
        return Err(format!("cannot read this process's CPU affinity: {}", io::Error::last_os_error()));
    }
    Ok(set_cores(unsafe { set.assume_init_ref() }))
}

/// Parses a list of cores such as `"2"`, `"0,1"`, `"0-3"` or `"0-1,4"` into an ascending list without
/// duplicates (`"1,1"` is `[1]`).
///
/// Errors, one sentence naming the offending value: an empty list or item, something that is not a core
/// number or a range `a-b` with `a ≤ b`, a core at or beyond the number of configured CPUs, or a core
/// this process may not run on ([`allowed_cores`]).
pub fn parse_cores(s: &str) -> Result<Vec<usize>, String> {
    let invalid = |why: String| Err(format!("invalid core list {s:?}: {why}"));
    if s.trim().is_empty() {
        return invalid("it is empty (expected e.g. \"0,1\" or \"0-3\")".to_owned());
    }
    let cpus = configured_cpus()?;
    let number = |t: &str| -> Result<usize, String> {
        let t = t.trim();
        if t.is_empty() || !t.bytes().all(|b| b.is_ascii_digit()) {
            return Err(format!("invalid core list {s:?}: {t:?} is not a core number"));
        }
        // Too many digits for a usize is a core that does not exist either.
        Ok(t.parse::<usize>().unwrap_or(usize::MAX))
    };
    let exists = |c: usize, t: &str| -> Result<usize, String> {
        if c < cpus {
            Ok(c)
        } else {
            Err(format!("invalid core list {s:?}: core {} does not exist (this machine has {cpus} CPUs)", t.trim()))
        }
    };
    let mut cores = Vec::new();
    for item in s.split(',') {
        if item.trim().is_empty() {
            return invalid("it has an empty item".to_owned());
        }
        match item.split_once('-') {
            Some((a_text, b_text)) => {
                let (a, b) = (number(a_text)?, number(b_text)?);
                if a > b {
                    return invalid(format!("the range {:?} is reversed", item.trim()));
                }
                // Both ends exist before the range is expanded (no huge allocation).
                cores.extend(exists(a, a_text)?..=exists(b, b_text)?);
            }
            None => cores.push(exists(number(item)?, item)?),
        }
    }
    cores.sort_unstable();
    cores.dedup();
    let allowed = allowed_cores()?;
    if let Some(c) = cores.iter().find(|c| allowed.binary_search(c).is_err()) {
        return invalid(format!("this process may not run on core {c} (allowed: {})", format_cores(&allowed)));
    }
    Ok(cores)
}

/// `cores` as a compact list, e.g. `0-3,6`.
fn format_cores(cores: &[usize]) -> String {
    let mut parts = Vec::new();
    let mut i = 0;
    while i < cores.len() {
        let mut j = i;
        while j + 1 < cores.len() && cores[j + 1] == cores[j] + 1 {
            j += 1;
        }
        parts.push(if j > i { format!("{}-{}", cores[i], cores[j]) } else { cores[i].to_string() });
        i = j + 1;
    }
    parts.join(",")
}

/// Restricts the calling thread to `cores` (`sched_setaffinity(0)`); processes (and threads) it spawns
/// afterwards inherit the restriction. Call it from the thread that spawns the children — for a
/// single-threaded process that is the whole process; threads already running keep their affinity.
///
/// Errors: an empty list, a core ≥ 1024 (`CPU_SETSIZE`), or a set the kernel refuses (e.g. no core of it
/// is allowed to this process).
pub fn pin_current_process(cores: &[usize]) -> Result<(), String> {
    if cores.is_empty() {
        return Err("cannot pin to an empty set of cores".to_owned());
    }
    // SAFETY: cpu_set_t is a plain bit array; all zeros is the empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    for &c in cores {
        if c >= libc::CPU_SETSIZE as usize {
            return Err(format!("cannot pin to core {c}: cores are numbered below {}", libc::CPU_SETSIZE));
        }
        unsafe { libc::CPU_SET(c, &mut set) };
    }
    let rc = unsafe { libc::sched_setaffinity(0, size_of::<libc::cpu_set_t>(), &set) };
    if rc != 0 {
        return Err(format!("cannot pin to cores {}: {}", format_cores(&set_cores(&set)), io::Error::last_os_error()));
    }
    Ok(())
}

/// The CPU time a process has used so far, user + system, seconds: fields 14 (`utime`) and 15 (`stime`)
/// of `/proc/<pid>/stat` over `sysconf(_SC_CLK_TCK)` (so a resolution of one clock tick, typically
/// 10 ms). Works for a zombie (an exited child not yet reaped); the times
/// of the process's own reaped children are not included.
pub fn process_cpu_seconds(pid: u32) -> Result<f64, String> {
    let path = format!("/proc/{pid}/stat");
    let stat = std::fs::read_to_string(&path).map_err(|e| format!("cannot read {path}: {e}"))?;
    let ticks = parse_stat_cpu_ticks(&stat).ok_or_else(|| format!("cannot parse {path}: {stat:?}"))?;
    let per_second = sysconf_positive(libc::_SC_CLK_TCK, "the clock tick rate")?;
    Ok(ticks as f64 / per_second as f64)
}

/// `utime + stime` (clock ticks) of the text of a `/proc/<pid>/stat`. The fields are counted after the
/// last `)`, which ends the command name (that may itself hold spaces and parentheses): field 3 (the
/// state) comes first, so fields 14 and 15 are the 12th and 13th there.
fn parse_stat_cpu_ticks(stat: &str) -> Option<u64> {
    let (_, rest) = stat.rsplit_once(')')?;
    let mut fields = rest.split_whitespace().skip(11);
    let utime: u64 = fields.next()?.parse().ok()?;
    let stime: u64 = fields.next()?.parse().ok()?;
    utime.checked_add(stime)
}

/// The resident memory of a process, bytes: the second field of `/proc/<pid>/statm` (resident pages)
/// times the page size.
pub fn rss_bytes(pid: u32) -> Result<u64, String> {
    let path = format!("/proc/{pid}/statm");
    let statm = std::fs::read_to_string(&path).map_err(|e| format!("cannot read {path}: {e}"))?;
    let pages: u64 = statm
        .split_whitespace()
        .nth(1)
        .and_then(|f| f.parse().ok())
        .ok_or_else(|| format!("cannot parse {path}: {statm:?}"))?;
    let page_size = sysconf_positive(libc::_SC_PAGESIZE, "the page size")?;
    Ok(pages.saturating_mul(page_size))
}

/// The private (anonymous) resident memory of process `pid`, bytes (`RssAnon` of `/proc/<pid>/status`):
/// its heap and stacks, without the shared memory it has touched (iceoryx2's segments are fixed in size,
/// but a subscriber that falls behind touches more of its publishers' sample pages, which counts in the
/// total RSS) or the mapped files.
pub fn anon_rss_bytes(pid: u32) -> Result<u64, String> {
    let path = format!("/proc/{pid}/status");
    let status = std::fs::read_to_string(&path).map_err(|e| format!("cannot read {path}: {e}"))?;
    let kib: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("RssAnon:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .ok_or_else(|| format!("no RssAnon in {path}"))?;
    Ok(kib * 1024)
}

/// CPU use (% of one core) of each process (name, pid) over `window`, from /proc (for processes that idle:
/// `uavloc launch`'s children waiting for messages that do not come yet).
pub fn idle_cpu(procs: &[(String, u32)], window: std::time::Duration) -> std::collections::BTreeMap<String, f64> {
    let before: Vec<(&String, u32, Option<f64>)> =
        procs.iter().map(|(name, pid)| (name, *pid, process_cpu_seconds(*pid).ok())).collect();
    let start = std::time::Instant::now();
    std::thread::sleep(window);
    let elapsed = start.elapsed().as_secs_f64();
    before
        .into_iter()
        .filter_map(|(name, pid, t0)| Some((name.clone(), 100.0 * (process_cpu_seconds(pid).ok()? - t0?) / elapsed)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::process::Command;

    #[test]
    fn the_private_resident_memory_grows_with_a_heap_allocation() {
        // The other tests of this binary run in threads beside this one and allocate and free too (once,
        // in CI, the growth read was 58.5 MiB of 64): the block is large and the margins allow for them.
        let me = std::process::id();
        let before = anon_rss_bytes(me).unwrap();
        let block = vec![1u8; 256 << 20];
        std::hint::black_box(&block);
        let during = anon_rss_bytes(me).unwrap();
        assert!(during >= before + (192 << 20), "{before} -> {during}");
        assert!(during <= rss_bytes(me).unwrap() + (32 << 20));
        assert!(anon_rss_bytes(u32::MAX).is_err());
    }

    #[test]
    fn parses_core_lists() {
        let allowed = allowed_cores().unwrap();
        assert!(!allowed.is_empty());
        let a = allowed[0];
        assert_eq!(parse_cores(&a.to_string()), Ok(vec![a]));
        assert_eq!(parse_cores(&format!(" {a} , {a}")), Ok(vec![a]));
        assert_eq!(parse_cores(&format!("{a}-{a}")), Ok(vec![a]));
        let all = format_cores(&allowed);
        assert_eq!(parse_cores(&all), Ok(allowed.clone()));
        if let [x, y, ..] = allowed[..] {
            assert_eq!(parse_cores(&format!("{y},{x},{y}")), Ok(vec![x, y]));
            if y == x + 1 {
                assert_eq!(parse_cores(&format!("{x}-{y}")), Ok(vec![x, y]));
                assert_eq!(parse_cores(&format!("{x}-{y},{x}")), Ok(vec![x, y]));
            }
        }
        let cpus = configured_cpus().unwrap();
        let bad = [
            String::new(),
            "  ".to_owned(),
            "x".to_owned(),
            "-1".to_owned(),
            "1.5".to_owned(),
            "0,".to_owned(),
            ",0".to_owned(),
            "0-".to_owned(),
            "0--1".to_owned(),
            "+0".to_owned(),
            "3-1".to_owned(),
            "1-0".to_owned(),
            cpus.to_string(),
            format!("0-{cpus}"),
            "99999999999999999999999".to_owned(),
            "0-18446744073709551615".to_owned(),
        ];
        for s in &bad {
            let err = parse_cores(s).unwrap_err();
            assert!(err.starts_with(&format!("invalid core list {s:?}: ")), "{s:?}: {err}");
            assert!(!err.contains('\n'), "{err}");
        }
        assert!(parse_cores("1-0").unwrap_err().contains("reversed"));
        assert!(
            parse_cores("0-99999999999999999999999").unwrap_err().contains("core 99999999999999999999999 does not")
        );
        assert!(parse_cores(&cpus.to_string()).unwrap_err().contains("does not exist"));
    }

    #[test]
    fn formats_core_lists_compactly() {
        assert_eq!(format_cores(&[]), "");
        assert_eq!(format_cores(&[3]), "3");
        assert_eq!(format_cores(&[0, 1, 2, 3, 6, 8, 9]), "0-3,6,8-9");
    }

    /// Pins this test's thread (the affinity is per thread, so other tests are not affected) and
    /// restores it.
    #[test]
    fn pins_and_restores_the_affinity() {
        let allowed = allowed_cores().unwrap();
        let first = allowed[0];
        pin_current_process(&[first]).unwrap();
        assert_eq!(allowed_cores().unwrap(), vec![first]);
        // Another core of the machine is no longer allowed.
        if let Some(&other) = allowed.get(1) {
            let err = parse_cores(&other.to_string()).unwrap_err();
            assert!(err.contains("may not run on core"), "{err}");
        }
        pin_current_process(&allowed).unwrap();
        assert_eq!(allowed_cores().unwrap(), allowed);
        assert!(pin_current_process(&[]).is_err());
        assert!(pin_current_process(&[libc::CPU_SETSIZE as usize]).is_err());
        assert_eq!(allowed_cores().unwrap(), allowed);
    }

    #[test]
    fn parses_stat_lines_with_odd_command_names() {
        let line = "1234 (a) b (c)) S 1 1234 1234 0 -1 4194304 100 0 0 0 250 17 0 0 20 0 1 0 12345 1000 200";
        assert_eq!(parse_stat_cpu_ticks(line), Some(267));
        assert_eq!(parse_stat_cpu_ticks("1234 (x) S 1 2"), None);
        assert_eq!(parse_stat_cpu_ticks("garbage"), None);
    }

    #[test]
    fn cpu_time_of_a_busy_child() {
        let mut child = Command::new("sh").args(["-c", "while :; do :; done"]).spawn().expect("spawn sh");
        let pid = child.id();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
        let mut cpu = 0.0;
        while cpu == 0.0 && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_millis(20));
            cpu = process_cpu_seconds(pid).unwrap();
        }
        child.kill().unwrap();
        child.wait().unwrap();
        assert!(cpu > 0.0, "{cpu}");
        assert!(process_cpu_seconds(u32::MAX).is_err());
    }

    #[test]
    fn own_cpu_time_and_memory() {
        // 100 ms of this thread's CPU time shows in the process's (in clock ticks of 10 ms; other tests'
        // threads only add to it).
        let thread_cpu = || {
            let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
            // SAFETY: clock_gettime writes into the timespec we own.
            unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
            ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
        };
        let before = process_cpu_seconds(std::process::id()).unwrap();
        let start = thread_cpu();
        let mut x = 0u64;
        while thread_cpu() - start < 0.1 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
        let after = process_cpu_seconds(std::process::id()).unwrap();
        assert!(after - before >= 0.08, "{before} s then {after} s after 0.1 s of CPU");
        let rss = rss_bytes(std::process::id()).unwrap();
        assert!(rss > 0 && rss.is_multiple_of(4096), "{rss}");
        assert!(rss_bytes(u32::MAX).is_err());
    }
}
