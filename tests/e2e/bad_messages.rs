//! A test publisher joins a running pipeline (a slow `uavloc launch`) on its domain and sends invalid
//! messages on every topic: NaN fields, a UAV count of 200, a negative σ, a covariance that is not positive
//! definite, an unknown version, valid-looking messages with a stale sequence number, and valid messages
//! of another run (another scenario's tag in the header, the newest sequence number there is). Every
//! receiver of a topic counts and ignores each of them; the run completes with exactly `simulate`'s
//! trajectory.

use crate::common;

use std::collections::BTreeMap;
use std::time::Duration;

use common::{Launch, assert_nothing_left, assert_same_run, domain, json_of, scratch};
use protocol::messages::{Fix, PlanInfo};
use protocol::services::{self, Domain};
use protocol::{Command, Estimate, Measurement, Message, Topic, TopicPublisher, Truth};

const UAVS: [[f64; 2]; 3] = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]];
/// Every bad message is numbered 1: below any sequence number a real process uses (they start at the
/// monotonic clock), so a message that is otherwise valid is stale.
const SEQ: u64 = 1;
const STEP: u64 = 1;

fn measurement() -> Measurement {
    Measurement::new(STEP, SEQ, &UAVS, &[-2012.3, -4010.9], &[28.7712; 3], &[0.1, 0.2, 0.3]).unwrap()
}

fn estimate() -> Estimate {
    let fix = Fix::Ok { position: [25000.0, 15000.0], covariance: [[4.0e4, 0.0], [0.0, 9.0e4]] };
    Estimate::new(STEP, SEQ, 7, &UAVS, &[0.1, 0.2, 0.3], fix).unwrap()
}

fn command() -> Command {
    let plan = PlanInfo {
        headings: &[0.5, 0.6, 0.7],
        waypoints: &UAVS,
        objective: 1.0e6,
        solver: "pso",
        objective_name: "analytical",
        plan_time_us: 100,
        active_constraints: 0,
        violated_constraints: 0,
    };
    Command::new(STEP, SEQ, 7, &plan).unwrap()
}

fn truth() -> Truth {
    Truth::new(STEP, SEQ, [25000.0, 15000.0])
}

fn with<T>(mut msg: T, f: impl FnOnce(&mut T)) -> T {
    f(&mut msg);
    msg
}

fn version<T: Message>(msg: T) -> T {
    with(msg, |m| m.header_mut().version = 99)
}

/// `msg` as a process of another run would send it: its run tag, and a sequence number above any a real
/// process uses (accepted, it would make every later real message of its topic stale).
fn other_run<T: Message>(msg: T) -> T {
    with(msg, |m| {
        m.header_mut().run = 0x0BAD_5EED;
        m.header_mut().seq = u64::MAX - 1;
    })
}

/// The bad messages of each topic, with the rejection kind each must be counted as.
struct Batch {
    measurements: Vec<(Measurement, &'static str)>,
    estimates: Vec<(Estimate, &'static str)>,
    commands: Vec<(Command, &'static str)>,
    truths: Vec<(Truth, &'static str)>,
}

fn batch() -> Batch {
    Batch {
        measurements: vec![
            (with(measurement(), |m| m.arrivals[1] = f64::NAN), "not_finite"),
            (with(measurement(), |m| m.count = 200), "bad_count"),
            (with(measurement(), |m| m.sigmas[2] = -28.0), "non_positive_sigma"),
            // Values that pass every other check but that the maths cannot take (the planner would fail
            // the step at every replay): a clock σ of 1e12 ns (3e11 m of range), a UAV 1e9 m away.
            (with(measurement(), |m| m.clock_sigmas_ns[0] = 1.0e12), "bad_field"),
            (with(measurement(), |m| m.uavs[1][0] = 1.0e9), "bad_field"),
            // Valid, with an old sequence number, from another publisher than emitter-sim: one measurement
            // source per run (it would be `stale` in the source's own stream, but it is not the source).
            (measurement(), "second_source"),
            (version(measurement()), "bad_version"),
            (other_run(measurement()), "other_run"),
        ],
        estimates: vec![
            (with(estimate(), |e| e.position[0] = f64::NAN), "not_finite"),
            (with(estimate(), |e| e.count = 200), "bad_count"),
            (with(estimate(), |e| e.covariance = [[-4.0e4, 0.0], [0.0, 9.0e4]]), "not_positive_definite"),
            // Positive definite, but beyond the floats' inverse: the planner could not plan it (it would
            // end the run); and biases' covariance that is not positive semi-definite.
            (with(estimate(), |e| e.covariance = [[1e-310, 0.0], [0.0, 1e-310]]), "not_positive_definite"),
            (with(estimate(), |e| e.bias_cov = [[-5.0e4, 0.0], [0.0, 0.0]]), "bad_field"),
            (estimate(), "stale"),
            (version(estimate()), "bad_version"),
            (other_run(estimate()), "other_run"),
        ],
        commands: vec![
            (with(command(), |c| c.headings[0] = f64::INFINITY), "not_finite"),
            (with(command(), |c| c.count = 200), "bad_count"),
            (command(), "stale"),
            (version(command()), "bad_version"),
            (other_run(command()), "other_run"),
        ],
        truths: vec![
            (with(truth(), |t| t.position[1] = f64::NAN), "not_finite"),
            (truth(), "stale"),
            (version(truth()), "bad_version"),
            (other_run(truth()), "other_run"),
        ],
    }
}

/// The publishers of a batch, kept until the run has ended: a sample whose publisher went away may be
/// gone before a receiver took it.
struct Publishers {
    _ports: (TopicPublisher<Measurement>, TopicPublisher<Estimate>, TopicPublisher<Command>, TopicPublisher<Truth>),
    _link: protocol::Link,
}

/// Publishes the batch on `domain` from this process, all at once: a few messages per topic, far fewer
/// than a subscriber's buffer holds, so none pushes out a real message.
fn send_batch(domain: &str, b: &Batch) -> Publishers {
    protocol::transport::quiet_logs();
    let d = Domain::new(domain).unwrap();
    let link = protocol::Link::open(protocol::TransportKind::Iceoryx2, &format!("{domain}-bad-publisher")).unwrap();
    let m = Topic::<Measurement>::publisher(&link, &services::measurement(&d)).unwrap();
    let e = Topic::<Estimate>::publisher(&link, &services::estimate(&d)).unwrap();
    let c = Topic::<Command>::publisher(&link, &services::command(&d)).unwrap();
    let t = Topic::<Truth>::publisher(&link, &services::truth(&d)).unwrap();
    b.measurements.iter().for_each(|(msg, _)| {
        m.send(msg).unwrap();
    });
    b.estimates.iter().for_each(|(msg, _)| {
        e.send(msg).unwrap();
    });
    b.commands.iter().for_each(|(msg, _)| {
        c.send(msg).unwrap();
    });
    b.truths.iter().for_each(|(msg, _)| {
        t.send(msg).unwrap();
    });
    Publishers { _ports: (m, e, c, t), _link: link }
}

#[test]
fn invalid_messages_are_counted_ignored_and_change_nothing() {
    let _scenario = common::scenario(module_path!());
    let d = domain("bad-msg", "all");
    let dir = scratch("bad-messages");
    let steps = "30";
    let mut launch = Launch::start(&d, &dir, &["--steps", steps, "--step-delay-ms", "30"]);
    // The real publishers have sent (and every receiver accepted) a few messages: a message numbered 1 is
    // stale from now on.
    launch.wait_for_step(2, Duration::from_secs(30));
    let b = batch();
    let sent = send_batch(&d, &b);
    // The batch went out while the run was still going.
    let last_logged =
        launch.events().iter().filter(|e| e["event"] == "step").filter_map(|e| e["step"].as_u64()).max().unwrap();
    assert!(last_logged < 30, "the run ended before the batch was sent");
    let run = launch.finish_json();
    drop(sent);

    // The trajectory is exactly simulate's: nothing bad was acted on.
    let sim = json_of(&["simulate", "--json", "--steps", steps]);
    assert_same_run(&sim, &run, "bad messages");
    assert_eq!(run["restarts"].as_u64(), Some(0), "nothing crashed");

    // Each process counted exactly the bad messages of the topics it subscribes to.
    let (nm, ne, nc, nt) = (b.measurements.len(), b.estimates.len(), b.commands.len(), b.truths.len());
    let by = &run["rejected_by"];
    // (The estimator reads the commands too, for the states they echo.)
    assert_eq!(by["estimator"].as_u64(), Some((nm + nc) as u64), "{run}");
    assert_eq!(by["planner"].as_u64(), Some(ne as u64), "{by}");
    assert_eq!(by["emitter-sim"].as_u64(), Some(nc as u64), "{by}");
    assert_eq!(by["monitor"].as_u64(), Some((nm + ne + nc + nt) as u64), "{by}");
    assert_eq!(run["rejected"].as_u64(), Some((2 * (nm + ne) + 3 * nc + nt) as u64));
    // Each process announced its count during the run (control `status`), and the monitor logged it: the
    // live view shows it from there.
    let events = common::read_events(&dir.join("run.jsonl"));
    for role in ["estimator", "planner", "emitter-sim"] {
        let last = events
            .iter()
            .filter(|e| e["event"] == "status" && e["role"] == role)
            .filter_map(|e| e["rejected"].as_u64())
            .max();
        assert_eq!(last, by[role].as_u64(), "{role}'s status");
    }

    // The monitor's log names every rejection by message type and reason.
    let mut expected: BTreeMap<(String, String), u64> = BTreeMap::new();
    let mut add = |kind: &str, reason: &str| *expected.entry((kind.into(), reason.into())).or_default() += 1;
    b.measurements.iter().for_each(|(_, r)| add("measurement", r));
    b.estimates.iter().for_each(|(_, r)| add("estimate", r));
    b.commands.iter().for_each(|(_, r)| add("command", r));
    b.truths.iter().for_each(|(_, r)| add("truth", r));
    let mut logged: BTreeMap<(String, String), u64> = BTreeMap::new();
    for e in read_rejections(&dir.join("run.jsonl")) {
        *logged.entry(e).or_default() += 1;
    }
    assert_eq!(logged, expected);
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

fn read_rejections(log: &std::path::Path) -> Vec<(String, String)> {
    common::read_events(log)
        .into_iter()
        .filter(|e| e["event"] == "rejected")
        .map(|e| (e["kind"].as_str().unwrap().to_string(), e["reason"].as_str().unwrap().to_string()))
        .collect()
}

/// A flood of malformed measurements (20 000 as fast as one publisher sends them) during a launch: each
/// process logs at most [`runtime::LogBudget::PER_SECOND`] rejection lines a second and says how many it
/// left out — it used to write a line each (32 MB in 4 s at 100 000 a second) — and the counts stay
/// exact: the monitor's `rejected` count is its logged lines plus the ones it said it left out.
#[test]
fn a_flood_of_bad_messages_is_logged_at_a_bounded_rate_with_exact_counts() {
    let _scenario = common::scenario(module_path!());
    let d = domain("bad-msg", "flood");
    let dir = scratch("bad-flood");
    let mut launch = Launch::start(&d, &dir, &["--steps", "300", "--step-delay-ms", "30"]);
    launch.wait_for_step(2, Duration::from_secs(30));
    let log = dir.join("run.jsonl");
    let said_left_out = || common::read_events(&log).iter().any(|e| e["event"] == "rejected_unlogged");
    {
        protocol::transport::quiet_logs();
        let domain = Domain::new(&d).unwrap();
        let node = protocol::Link::open(protocol::TransportKind::Iceoryx2, &format!("{d}-flood")).unwrap();
        let m = Topic::<Measurement>::publisher(&node, &services::measurement(&domain)).unwrap();
        let bad = with(measurement(), |m| m.arrivals[1] = f64::NAN);
        // A flood, then one more a second later, whose line says how many of the flood were left out. A
        // loaded machine may starve the monitor so that fewer than its budget reach it (the buffers hold
        // 64): then the flood comes again, until the monitor said it left some out.
        for round in 1..=5 {
            for k in 0..20_000 {
                m.send(&bad).unwrap();
                // Bursts the receivers' buffers (64) can hold, so that most of the flood reaches them.
                if k % 16 == 15 {
                    std::thread::sleep(Duration::from_micros(200));
                }
            }
            std::thread::sleep(Duration::from_millis(1100));
            m.send(&bad).unwrap();
            let deadline = std::time::Instant::now() + Duration::from_secs(2);
            while !said_left_out() && std::time::Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(20));
            }
            if said_left_out() {
                break;
            }
            assert!(round < 5, "five floods and the monitor never left a line out:\n{}", launch.stderr_text());
        }
    }
    let stderr_path = launch.stderr.clone();
    let run = launch.finish_json();
    let stderr = std::fs::read_to_string(stderr_path).unwrap();
    let monitor = run["rejected_by"]["monitor"].as_u64().unwrap();
    assert!(monitor > runtime::LogBudget::PER_SECOND, "the flood did not reach the monitor: {monitor}");
    let events = common::read_events(&dir.join("run.jsonl"));
    let times: Vec<u64> =
        events.iter().filter(|e| e["event"] == "rejected").map(|e| e["t_ns"].as_u64().unwrap()).collect();
    let logged = times.len() as u64;
    let unlogged: u64 =
        events.iter().filter(|e| e["event"] == "rejected_unlogged").filter_map(|e| e["count"].as_u64()).sum();
    // Bounded: any one second of the log holds at most two budget windows' lines, however long a loaded
    // machine took over the flood. Exact: the lines and the counts left out add up to the node's count.
    let busiest = (0..times.len()).map(|i| times[i..].partition_point(|t| *t < times[i] + 1_000_000_000)).max();
    assert!(busiest.unwrap_or(0) as u64 <= 2 * runtime::LogBudget::PER_SECOND, "{busiest:?} lines in one second");
    assert!(unlogged > 0 && logged < monitor, "{logged} lines logged of {monitor}: the flood was not summarised");
    assert_eq!(logged + unlogged, monitor, "{logged} logged + {unlogged} left out");
    assert!(stderr.len() < 200_000, "{} bytes of stderr", stderr.len());
    assert_eq!(run["steps"].as_array().unwrap().len(), 301);
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}
