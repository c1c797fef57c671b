//! Real iceoryx2 round trips (in-process threads; every test has its own domain so parallel tests and
//! leftovers of earlier runs never share a service).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use protocol::messages::{Fix, PlanInfo};
use protocol::services::{self, Domain};
use protocol::transport::{MAX_PUBLISHERS, SUBSCRIBER_BUFFER, TopicEvents};
use protocol::{Command, Estimate, Link, Measurement, Message, Topic, TransportError, TransportKind, Truth, now_ns};

/// A process link over iceoryx2 (these tests cover the iceoryx2 transport; `uds.rs` the sockets).
fn iox_link(name: &str) -> Result<Link, TransportError> {
    Link::open(TransportKind::Iceoryx2, name)
}

fn unique_domain() -> Domain {
    protocol::transport::quiet_logs();
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    Domain::new(&format!("test-{}-{}-{n}", std::process::id(), now_ns() % 1_000_000_000)).unwrap()
}

/// The bytes of a message.
fn bytes_of<T: Message>(msg: &T) -> &[u8] {
    // SAFETY: the message types are repr(C) with no implicit padding (checked by the layout tests in the
    // crate), so every byte is an initialised field byte; the slice lives as long as `msg`.
    unsafe { core::slice::from_raw_parts((msg as *const T).cast::<u8>(), size_of::<T>()) }
}

const UAVS: [[f64; 2]; 5] = [[0.0, 0.0], [1000.5, -3.25], [0.125, 999.0], [-500.0, 250.0], [1e-9, -1e7]];

fn measurement(seq: u64) -> Measurement {
    let mut m = Measurement::new(
        7,
        seq,
        &UAVS,
        &[1.5, -2.5, 3.5, -4.5],
        &[3.0, 3.1, 3.2, 3.3, 3.4],
        &[0.1, -0.2, 0.3, -0.4, 3.1],
    )
    .unwrap();
    m.header.stamps.trigger_command_published_ns = 11;
    m.header.stamps.trigger_command_received_ns = 12;
    m
}

fn estimate(seq: u64, fix: Fix) -> Estimate {
    Estimate::from_measurement(&measurement(seq), 123_456, seq, 0xDEAD_BEEF, fix).unwrap()
}

fn command(seq: u64) -> Command {
    let plan = PlanInfo {
        headings: &[0.5, -0.5, 1.5, -1.5, 3.0],
        waypoints: &UAVS,
        objective: 42.125,
        solver: "pso",
        objective_name: "trace-crlb",
        plan_time_us: 321,
        active_constraints: 0b1011,
        violated_constraints: 0b10,
    };
    Command::from_estimate(&estimate(seq, Fix::Failed), 654_321, seq, 99, &plan).unwrap()
}

/// Sends `msg` and receives it in the same thread; checks that every byte except the publish stamps
/// survived and that the stamps are the ones `send` reported.
fn round_trip<T: Message>(name: &str, msg: T) {
    let node = iox_link(&format!("{name}-node").replace('/', "-")).unwrap();
    let subscriber = Topic::<T>::subscriber(&node, name).unwrap();
    let publisher = Topic::<T>::publisher(&node, name).unwrap();
    let sent = publisher.send(&msg).unwrap();
    assert_eq!(sent.subscribers, 1);
    let received = subscriber.receive_all().unwrap();
    assert_eq!(received.len(), 1);
    let mut expected = msg;
    expected.header_mut().stamps.mark_published(T::KIND, sent.published_ns);
    assert_eq!(bytes_of(&received[0]), bytes_of(&expected), "{:?}", T::KIND);
    assert_ne!(received[0].header().stamps.published_ns, 0);
    assert_eq!(received[0].validate(None), Ok(()));
    assert!(subscriber.receive_all().unwrap().is_empty(), "drained");
}

#[test]
fn every_message_type_round_trips_through_a_real_service() {
    let d = unique_domain();
    round_trip(&services::measurement(&d), measurement(1));
    round_trip(
        &services::estimate(&d),
        estimate(2, Fix::Ambiguous { position: [3.5, -7.25], covariance: [[4.0, 0.5], [0.5, 2.0]] }),
    );
    // A failed estimate carries NaNs, compared bytewise.
    let d2 = unique_domain();
    round_trip(&services::estimate(&d2), estimate(2, Fix::Failed));
    round_trip(&services::command(&d), command(3));
    let mut truth = Truth::new(7, 4, [123.5, -456.75]);
    truth.header.stamps.measurement_published_ns = 5;
    round_trip(&services::truth(&d), truth);
}

#[test]
fn subscriber_in_a_waitset_wakes_on_notify() {
    let d = unique_domain();
    let name = services::measurement(&d);
    let (ready_tx, ready_rx) = mpsc::channel();
    let sub_name = name.clone();
    let receiver = thread::spawn(move || {
        let node = iox_link("waitset-subscriber").unwrap();
        let subscriber = Topic::<Measurement>::subscriber(&node, &sub_name).unwrap();
        let waitset = protocol::transport::waitset().unwrap();
        let guard = waitset.attach_notification(&subscriber).unwrap();
        ready_tx.send(()).unwrap();
        let mut got = Vec::new();
        let start = Instant::now();
        while got.is_empty() && start.elapsed() < Duration::from_secs(10) {
            waitset
                .wait_and_process_once_with_timeout(
                    |id| {
                        if id.has_event_from(&guard) {
                            got.extend(subscriber.receive_all().unwrap().into_iter().map(|m| (m, now_ns())));
                        }
                        CallbackProgression::Continue
                    },
                    Duration::from_secs(5),
                )
                .unwrap();
        }
        got
    });
    ready_rx.recv_timeout(Duration::from_secs(10)).unwrap();
    let node = iox_link("waitset-publisher").unwrap();
    let publisher = Topic::<Measurement>::publisher(&node, &name).unwrap();
    let sent = publisher.send(&measurement(5)).unwrap();
    let got = receiver.join().unwrap();
    assert_eq!(got.len(), 1, "woken within the timeout with exactly the message sent");
    let (m, received_ns) = got[0];
    assert_eq!(m.header.seq, 5);
    assert_eq!(m.header.stamps.published_ns, sent.published_ns);
    let latency = m.header.stamps.age_ns(received_ns).unwrap();
    assert!(latency < 2_000_000_000, "wake-up took {latency} ns");
}

#[test]
fn spin_then_block_wait_times_out_then_receives() {
    let d = unique_domain();
    let name = services::estimate(&d);
    let node = iox_link("wait-test").unwrap();
    let subscriber = Topic::<Estimate>::subscriber(&node, &name).unwrap();
    let start = Instant::now();
    assert!(subscriber.wait(Duration::from_micros(200), Duration::from_millis(50)).unwrap().is_empty());
    assert!(start.elapsed() >= Duration::from_millis(40), "waited {:?}", start.elapsed());

    let (tx, rx) = mpsc::channel::<()>();
    let pub_name = name.clone();
    let sender = thread::spawn(move || {
        let node = iox_link("wait-test-publisher").unwrap();
        let publisher = Topic::<Estimate>::publisher(&node, &pub_name).unwrap();
        rx.recv().unwrap();
        thread::sleep(Duration::from_millis(20));
        publisher.send(&estimate(1, Fix::Failed)).unwrap();
        // Keep the publisher alive until the message is received (dropping it is fine too: the sample
        // stays in the subscriber's buffer; this keeps the test independent of that).
        rx.recv().ok();
    });
    // The publisher-created event may wake a wait with nothing to receive: wait again.
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    tx.send(()).unwrap();
    while got.is_empty() && Instant::now() < deadline {
        got = subscriber.wait(Duration::from_micros(100), Duration::from_secs(5)).unwrap();
    }
    drop(tx);
    sender.join().unwrap();
    assert_eq!(got.len(), 1);
    assert_eq!(got[0].header.seq, 1);
}

#[test]
fn lifecycle_events_and_several_publishers() {
    let d = unique_domain();
    let name = services::command(&d);
    let node = iox_link("lifecycle").unwrap();
    let subscriber = Topic::<Command>::subscriber(&node, &name).unwrap();
    let mut events = TopicEvents::default();
    let mut out = Vec::new();
    {
        // A planner swap: the old and the new planner publish on the same topic for a while.
        let publishers: Vec<_> =
            (0..MAX_PUBLISHERS).map(|_| Topic::<Command>::publisher(&node, &name).unwrap()).collect();
        let extra = Topic::<Command>::publisher(&node, &name);
        assert!(matches!(extra, Err(TransportError::Failed { .. })), "at most {MAX_PUBLISHERS} publishers");
        for (i, p) in publishers.iter().enumerate() {
            p.send(&command(10 + i as u64)).unwrap();
        }
        assert_eq!(subscriber.receive_into(&mut out).unwrap().samples, MAX_PUBLISHERS as u64);
        let e = subscriber.consume_wakeups().unwrap();
        events.samples += e.samples;
        events.publishers_created += e.publishers_created;
    }
    subscriber.receive_into(&mut out).unwrap();
    let e = subscriber.consume_wakeups().unwrap();
    assert_eq!(
        out.iter().map(|c| c.header.seq).collect::<Vec<_>>(),
        (10..10 + MAX_PUBLISHERS as u64).collect::<Vec<_>>()
    );
    assert_eq!(events.publishers_created, MAX_PUBLISHERS as u64);
    assert!(events.samples >= 1, "sample notifications may be coalesced: {events:?}");
    assert_eq!(e.publishers_dropped, MAX_PUBLISHERS as u64);
}

#[test]
fn subscriber_buffer_keeps_the_newest_samples() {
    let d = unique_domain();
    let name = services::truth(&d);
    let node = iox_link("buffer").unwrap();
    let subscriber = Topic::<Truth>::subscriber(&node, &name).unwrap();
    let publisher = Topic::<Truth>::publisher(&node, &name).unwrap();
    let total = SUBSCRIBER_BUFFER as u64 + 5;
    for seq in 1..=total {
        publisher.send(&Truth::new(seq, seq, [0.0, 0.0])).unwrap();
    }
    let got: Vec<u64> = subscriber.receive_all().unwrap().iter().map(|t| t.header.seq).collect();
    assert_eq!(got, (total - SUBSCRIBER_BUFFER as u64 + 1..=total).collect::<Vec<_>>());
}

#[test]
fn a_late_subscriber_gets_no_history() {
    let d = unique_domain();
    let name = services::measurement(&d);
    let node = iox_link("history").unwrap();
    let publisher = Topic::<Measurement>::publisher(&node, &name).unwrap();
    assert_eq!(publisher.send(&measurement(1)).unwrap().subscribers, 0);
    let subscriber = Topic::<Measurement>::subscriber(&node, &name).unwrap();
    assert!(subscriber.receive_all().unwrap().is_empty());
    // Sent from the sample loaned ahead while nobody subscribed: it still reaches the new subscriber.
    publisher.send(&measurement(2)).unwrap();
    let got = subscriber.receive_all().unwrap();
    assert_eq!(got.iter().map(|m| m.header.seq).collect::<Vec<_>>(), [2]);
}

#[test]
fn every_send_writes_its_own_message_into_the_sample_loaned_ahead() {
    // The publisher loans the next sample right after a send: each message must still arrive whole and
    // as sent, at every subscriber, also when the pool's chunks have all been used several times over
    // (more sends than the subscribers' buffers hold) and one subscriber never reads.
    let d = unique_domain();
    let name = services::measurement(&d);
    let node = iox_link("ahead").unwrap();
    let readers: Vec<_> = (0..3).map(|_| Topic::<Measurement>::subscriber(&node, &name).unwrap()).collect();
    let idle = Topic::<Measurement>::subscriber(&node, &name).unwrap();
    let publisher = Topic::<Measurement>::publisher(&node, &name).unwrap();
    for seq in 1..=4 * SUBSCRIBER_BUFFER as u64 {
        let mut m = measurement(seq);
        m.header.step = seq;
        m.arrivals[1] = seq as f64;
        let sent = publisher.send(&m).unwrap();
        assert_eq!(sent.subscribers, 4);
        m.header.stamps.mark_published(Measurement::KIND, sent.published_ns);
        for r in &readers {
            let got = r.receive_all().unwrap();
            assert_eq!(got.len(), 1, "message {seq}");
            assert_eq!(bytes_of(&got[0]), bytes_of(&m), "message {seq}");
        }
    }
    let kept: Vec<u64> = idle.receive_all().unwrap().iter().map(|m| m.header.seq).collect();
    let total = 4 * SUBSCRIBER_BUFFER as u64;
    assert_eq!(kept, (total - SUBSCRIBER_BUFFER as u64 + 1..=total).collect::<Vec<_>>());
}

#[test]
fn a_different_message_type_cannot_open_a_topic() {
    let d = unique_domain();
    let name = services::measurement(&d);
    let node = iox_link("types").unwrap();
    let _publisher = Topic::<Measurement>::publisher(&node, &name).unwrap();
    let err = Topic::<Estimate>::subscriber(&node, &name).unwrap_err();
    assert!(err.to_string().contains("IncompatibleTypes"), "{err}");
}

#[test]
fn bad_names_are_reported() {
    let node = iox_link("names").unwrap();
    let err = Topic::<Truth>::publisher(&node, "").unwrap_err();
    assert!(matches!(err, TransportError::BadName { what: "service", .. }), "{err}");
}

/// Set in a child copy of this test binary: the topic name its publisher uses before it is killed.
const CHILD_ENV: &str = "UAVLOC_PROTOCOL_TEST_CHILD_TOPIC";

/// Not a test of its own: run as a child process by `a_killed_publisher_is_cleaned_up`.
#[test]
fn helper_publisher_process_to_be_killed() {
    let Ok(name) = std::env::var(CHILD_ENV) else { return };
    protocol::transport::quiet_logs();
    let node = iox_link("doomed-publisher").unwrap();
    let publisher = Topic::<Measurement>::publisher(&node, &name).unwrap();
    publisher.send(&measurement(1)).unwrap();
    println!("READY"); // libtest may have printed "test <name> ... " on the same line
    thread::sleep(Duration::from_secs(60));
    panic!("the parent should have killed this process");
}

#[test]
fn a_killed_publisher_is_cleaned_up() {
    use std::io::{BufRead, BufReader};
    use std::process::{Command as Process, Stdio};

    let d = unique_domain();
    let name = services::measurement(&d);
    let node = iox_link("survivor").unwrap();
    let subscriber = Topic::<Measurement>::subscriber(&node, &name).unwrap();

    let mut child = Process::new(std::env::current_exe().unwrap())
        .args(["iox::helper_publisher_process_to_be_killed", "--exact", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, &name)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = BufReader::new(child.stdout.take().unwrap());
    assert!(stdout.lines().map_while(Result::ok).any(|l| l.ends_with("READY")), "child did not start");
    let got = subscriber.receive_all().unwrap();
    assert_eq!(got.iter().map(|m| m.header.seq).collect::<Vec<_>>(), vec![1]);
    // SIGKILL: no destructor runs, the child's node and ports are left behind. (Samples of a dead
    // publisher not yet received are lost as soon as anyone cleans the dead node up, which parallel tests
    // creating nodes may do at any time: hence the receive above, before the kill.)
    child.kill().unwrap();
    child.wait().unwrap();

    // A new node cleans the dead one up (or another test's node did already); the subscriber hears of it.
    let _cleaner = iox_link("cleaner").unwrap();
    let mut events = TopicEvents::default();
    let deadline = Instant::now() + Duration::from_secs(5);
    while events.publishers_dead == 0 && Instant::now() < deadline {
        protocol::transport::cleanup_dead_nodes(node.node());
        let e = subscriber.consume_wakeups().unwrap();
        events.publishers_dead += e.publishers_dead;
        thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(events.publishers_dead, 1, "{events:?}");

    // The dead publisher's slot is free again: a full set of publishers can attach.
    let publishers: Vec<_> =
        (0..MAX_PUBLISHERS).map(|_| Topic::<Measurement>::publisher(&node, &name).unwrap()).collect();
    publishers[0].send(&measurement(2)).unwrap();
    assert_eq!(subscriber.receive_all().unwrap()[0].header.seq, 2);
}

/// A scattered duration below `max` for round trip `i` (and `salt`: the two ends differ).
fn scattered(i: u64, salt: u64, max: Duration) -> Duration {
    Duration::from_nanos(((i ^ salt).wrapping_mul(2_654_435_761) >> 7) % max.as_nanos() as u64)
}

/// Busy-poll budgets (0–40 µs) that, with the sender's delays ([`busy_for`] 0–50 µs), move the end of a
/// wait's poll across the other end's send: in the ping-pong below a message often comes just as a wait
/// stops polling and gets ready to block.
fn spin_of(i: u64, salt: u64) -> Duration {
    scattered(i, salt, Duration::from_micros(40))
}

/// Keeps the CPU busy for `d` (a sender's work before it answers).
fn busy_for(d: Duration) {
    let start = Instant::now();
    while start.elapsed() < d {
        std::hint::spin_loop();
    }
}

/// The wake-up protocol (module docs of `protocol::transport`): a subscriber consumes its wake-ups only just
/// before it blocks, so a notification to a subscriber that is polling costs the publisher no system call.
/// If a wake-up were ever lost — consumed after the last look at the buffer instead of before it — a
/// blocked wait would sit out its whole timeout. 20 000 ping-pong round trips, both ends waiting with
/// varying poll budgets (one through `TopicSubscriber::wait`, the other through a `WaitSet`, as the node
/// runtime waits) and answering after varying delays: no wait may last anywhere near its timeout (a
/// message it was not woken for is found only at the timeout, or never). (With
/// the two steps of `about_to_block` swapped, this test failed 5 runs of 5.)
#[test]
fn no_wake_up_is_lost_between_polling_and_blocking() {
    const ROUND_TRIPS: u64 = 20_000;
    const TIMEOUT: Duration = Duration::from_secs(2);
    let d = unique_domain();
    let (ping, pong) = (services::measurement(&d), services::command(&d));
    let (ready_tx, ready_rx) = mpsc::channel();
    let (ping_e, pong_e) = (ping.clone(), pong.clone());
    let echo = thread::spawn(move || -> Result<u64, String> {
        let node = iox_link("echo").unwrap();
        let sub = Topic::<Measurement>::subscriber(&node, &ping_e).unwrap();
        let publisher = Topic::<Command>::publisher(&node, &pong_e).unwrap();
        let waitset = protocol::transport::waitset().unwrap();
        let _guard = waitset.attach_notification(&sub).unwrap();
        ready_tx.send(()).unwrap();
        let (mut i, mut stalls) = (0u64, 0u64);
        while i < ROUND_TRIPS {
            let start = Instant::now();
            protocol::transport::wait_any(&waitset, spin_of(i, 1), TIMEOUT, &[&sub]).unwrap();
            let got = sub.receive_all().unwrap();
            if start.elapsed() >= TIMEOUT / 2 {
                stalls += 1;
                if stalls > 2 {
                    return Err(format!("the echo's waits timed out {stalls} times (round trip {i})"));
                }
            }
            for m in got {
                busy_for(scattered(m.header.seq, 2, Duration::from_micros(50)));
                publisher.send(&command(m.header.seq)).unwrap();
                i = m.header.seq + 1;
            }
        }
        Ok(stalls)
    });
    ready_rx.recv_timeout(Duration::from_secs(10)).unwrap();
    let node = iox_link("pinger").unwrap();
    let publisher = Topic::<Measurement>::publisher(&node, &ping).unwrap();
    let sub = Topic::<Command>::subscriber(&node, &pong).unwrap();
    while publisher.subscriber_count().unwrap() < 1 || sub.publisher_count().unwrap() < 1 {
        thread::sleep(Duration::from_millis(1));
    }
    let mut stalls = 0u64;
    let mut worst = Duration::ZERO;
    for i in 0..ROUND_TRIPS {
        busy_for(scattered(i, 3, Duration::from_micros(50)));
        publisher.send(&measurement(i)).unwrap();
        let sent = Instant::now();
        loop {
            let start = Instant::now();
            let got = sub.wait(spin_of(i, 4), TIMEOUT).unwrap();
            if start.elapsed() >= TIMEOUT / 2 {
                stalls += 1;
            }
            if got.iter().any(|c| c.header.seq == i) || stalls > 2 {
                break;
            }
        }
        worst = worst.max(sent.elapsed());
        if stalls > 2 {
            break;
        }
    }
    let echo_stalls = echo.join().unwrap();
    assert_eq!(stalls, 0, "the pinger's waits sat out their timeout (worst round trip {worst:?})");
    assert_eq!(echo_stalls, Ok(0), "the echo's waits sat out their timeout");
}

/// A topic's event service takes event ids up to `event_id::MAX` only: every wait of every listener
/// visits one counter per id, so iceoryx2's default (255) would cost 256 atomic swaps per listener and
/// wait. A foreign client opening the service with iceoryx2's defaults is still compatible. Read back
/// from the service another link opens after a publisher created it.
#[test]
fn event_services_take_only_the_ids_in_use() {
    use protocol::transport::event_id;
    let d = unique_domain();
    let name = services::estimate(&d);
    let link = iox_link("event-ids").unwrap();
    let _publisher = Topic::<Estimate>::publisher(&link, &name).unwrap();
    let other = iox_link("event-ids-reader").unwrap();
    assert_eq!(protocol::transport::iox::event_id_limit(other.node(), &name).unwrap(), event_id::MAX);
    assert!(event_id::MAX >= event_id::SAMPLE.max(event_id::PUBLISHER_CREATED).max(event_id::PUBLISHER_DROPPED));
    assert_eq!(event_id::MAX, event_id::PUBLISHER_DEAD);
}

#[test]
fn a_sample_is_in_hand_once_taken_not_once_seen() {
    // A poll only looks (the sample stays in the queue); the receive takes it, and its stamp is then.
    let domain = unique_domain();
    let link = iox_link(&services::node_name(&domain, "in-hand")).unwrap();
    let name = services::measurement(&domain);
    let sub = Topic::<Measurement>::subscriber(&link, &name).unwrap();
    let publisher = Topic::<Measurement>::publisher(&link, &name).unwrap();
    let published = publisher.send(&measurement(1)).unwrap().published_ns;
    assert!(sub.has_samples().unwrap());
    std::thread::sleep(Duration::from_millis(5));
    let before = now_ns();
    let (got, in_hand) = sub.receive_stamped().unwrap();
    assert_eq!(got.len(), 1);
    assert!(published < before && before <= in_hand && in_hand <= now_ns(), "{published} < {before} ≤ {in_hand}");
    // A batch is stamped when its last message was taken: none of it was published after.
    let last = (2..5).map(|seq| publisher.send(&measurement(seq)).unwrap().published_ns).max().unwrap();
    let (got, in_hand) = sub.receive_stamped().unwrap();
    assert!(got.len() == 3 && in_hand >= last);
}
