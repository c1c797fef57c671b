//! The Unix-domain-socket transport: real sockets (every test has its own topic names, so parallel tests
//! never share a socket directory).

use std::os::unix::fs::PermissionsExt;
use std::os::unix::net::UnixDatagram;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use protocol::messages::{Fix, PlanInfo};
use protocol::transport::{uds, wait_any, waitset};
use protocol::{
    Command, Control, ControlKind, Estimate, Link, Measurement, Message, Topic, TransportKind, Truth, now_ns,
};

fn unique(name: &str) -> String {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    format!("udstest-{}-{}-{n}/{name}", std::process::id(), now_ns() % 1_000_000_000)
}

fn link() -> Link {
    protocol::transport::quiet_logs();
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    Link::open(TransportKind::Uds, &format!("udstest-{}-{n}", std::process::id())).unwrap()
}

const UAVS: [[f64; 2]; 4] = [[0.0, 0.0], [1000.5, -3.25], [0.125, 999.0], [-500.0, 250.0]];

fn measurement(step: u64, seq: u64) -> Measurement {
    Measurement::new(step, seq, &UAVS, &[1.5, -2.5, 3.5], &[3.0, 3.1, 3.2, 3.3], &[0.1, -0.2, 0.3, -0.4]).unwrap()
}

/// Sends `msg` and receives it in the same thread: every byte but the publish stamps survives.
fn round_trip<T: Message>(msg: T) {
    let link = link();
    let name = unique(T::KIND.name());
    let sub = Topic::<T>::subscriber(&link, &name).unwrap();
    let publisher = Topic::<T>::publisher(&link, &name).unwrap();
    let sent = publisher.send(&msg).unwrap();
    assert_eq!(sent.subscribers, 1);
    let got = sub.receive_all().unwrap();
    assert_eq!(got.len(), 1, "{:?}", T::KIND);
    let mut expected = msg;
    expected.header_mut().stamps.mark_published(T::KIND, sent.published_ns);
    assert_eq!(got[0].as_bytes(), expected.as_bytes(), "{:?}", T::KIND);
    assert_eq!(got[0].validate(None), Ok(()));
    assert!(sub.receive_all().unwrap().is_empty(), "drained");
}

#[test]
fn every_message_type_round_trips_byte_for_byte() {
    round_trip(measurement(3, 1));
    let e = Estimate::from_measurement(
        &measurement(3, 1),
        42,
        2,
        7,
        Fix::Ok { position: [1.0, 2.0], covariance: [[4.0, 1.0], [1.0, 3.0]] },
    )
    .unwrap();
    round_trip(e);
    let plan = PlanInfo {
        headings: &[0.5, -0.5, 1.5, -1.5],
        waypoints: &UAVS,
        objective: 42.125,
        solver: "pso",
        objective_name: "trace-crlb",
        plan_time_us: 321,
        active_constraints: 0b1011,
        violated_constraints: 0b10,
    };
    round_trip(Command::from_estimate(&e, 77, 3, 99, &plan).unwrap());
    round_trip(Truth::new(3, 4, [25_000.0, 15_000.0]));
    round_trip(Control::new(ControlKind::Hello, 0, 5, 6, 7, "planner", "").unwrap());
}

#[test]
fn fans_out_to_every_subscriber_and_counts_participants() {
    let link = link();
    let name = unique("fanout");
    let a = Topic::<Measurement>::subscriber(&link, &name).unwrap();
    let b = Topic::<Measurement>::subscriber(&link, &name).unwrap();
    let publisher = Topic::<Measurement>::publisher(&link, &name).unwrap();
    assert_eq!(publisher.subscriber_count().unwrap(), 2);
    assert_eq!(publisher.publisher_count().unwrap(), 1);
    assert_eq!(a.publisher_count().unwrap(), 1);
    for seq in 1..=5 {
        assert_eq!(publisher.send(&measurement(seq, seq)).unwrap().subscribers, 2);
    }
    for sub in [&a, &b] {
        let got = sub.receive_all().unwrap();
        assert_eq!(got.iter().map(|m| m.header.seq).collect::<Vec<_>>(), [1, 2, 3, 4, 5], "in order, none lost");
    }
    drop(b);
    assert_eq!(publisher.send(&measurement(6, 6)).unwrap().subscribers, 1, "a dropped subscriber is gone");
    assert_eq!(publisher.subscriber_count().unwrap(), 1);
    assert_eq!(publisher.dropped(), 0);
}

#[test]
fn a_copy_sent_again_carries_no_publish_stamp() {
    let link = link();
    let name = unique("copy");
    let sub = Topic::<Measurement>::subscriber(&link, &name).unwrap();
    let publisher = Topic::<Measurement>::publisher(&link, &name).unwrap();
    publisher.send(&measurement(4, 1)).unwrap();
    let first = sub.receive_all().unwrap()[0];
    assert!(first.header.stamps.published_ns > 0 && first.header.stamps.measurement_published_ns > 0);
    // The message as received, stamps and all, sent again: its publish stamps are cleared, nothing else.
    assert_eq!(publisher.publish(&first, true).unwrap().published_ns, 0);
    let copy = sub.receive_all().unwrap()[0];
    let mut expected = first;
    expected.header.stamps.mark_published(Measurement::KIND, 0);
    assert_eq!(copy, expected);
    // Not a copy: stamped anew.
    assert!(publisher.publish(&copy, false).unwrap().published_ns > first.header.stamps.published_ns);
    assert!(sub.receive_all().unwrap()[0].header.stamps.published_ns > first.header.stamps.published_ns);
    assert_eq!((copy.header.stamps.published_ns, copy.header.stamps.measurement_published_ns), (0, 0));
}

#[test]
fn a_publisher_finds_a_subscriber_that_comes_later() {
    let link = link();
    let name = unique("late");
    let publisher = Topic::<Truth>::publisher(&link, &name).unwrap();
    assert_eq!(publisher.send(&Truth::new(0, 1, [1.0, 2.0])).unwrap().subscribers, 0);
    let sub = Topic::<Truth>::subscriber(&link, &name).unwrap();
    assert_eq!(publisher.send(&Truth::new(1, 2, [1.0, 2.0])).unwrap().subscribers, 1);
    let got = sub.receive_all().unwrap();
    assert_eq!(got.len(), 1);
    assert_eq!(got[0].header.step, 1, "no history: the message before it subscribed is not delivered");
}

#[test]
fn a_dead_subscribers_socket_is_removed_by_the_next_send() {
    let link = link();
    let name = unique("dead");
    let publisher = Topic::<Truth>::publisher(&link, &name).unwrap();
    // What a SIGKILLed subscriber leaves: a bound socket file nobody listens on any more.
    let dir = uds::topic_dir(&name);
    let stale = dir.join(format!("s.{}.999999", std::process::id()));
    drop(UnixDatagram::bind(&stale).unwrap());
    assert!(stale.exists());
    let live = Topic::<Truth>::subscriber(&link, &name).unwrap();
    assert_eq!(publisher.send(&Truth::new(0, 1, [1.0, 2.0])).unwrap().subscribers, 1);
    assert!(!stale.exists(), "the stale socket file was removed");
    assert_eq!(live.receive_all().unwrap().len(), 1);
}

#[test]
fn malformed_datagrams_are_counted_and_skipped() {
    let link = link();
    let name = unique("malformed");
    let sub = Topic::<Measurement>::subscriber(&link, &name).unwrap();
    let publisher = Topic::<Measurement>::publisher(&link, &name).unwrap();
    let path = std::fs::read_dir(uds::topic_dir(&name))
        .unwrap()
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| p.file_name().unwrap().to_str().unwrap().starts_with("s."))
        .unwrap();
    let raw = UnixDatagram::unbound().unwrap();
    raw.send_to(&[1, 2, 3], &path).unwrap();
    raw.send_to(&vec![0u8; size_of::<Measurement>() + 8], &path).unwrap();
    publisher.send(&measurement(1, 1)).unwrap();
    let mut out = Vec::new();
    let events = sub.receive_into(&mut out).unwrap();
    assert_eq!(out.len(), 1);
    assert_eq!(events.samples, 1);
    assert_eq!(events.other, 2, "both wrong-sized datagrams counted");
}

#[test]
fn a_waitset_wakes_on_a_socket_subscriber() {
    let link = link();
    let name = unique("waitset");
    let sub = Topic::<Measurement>::subscriber(&link, &name).unwrap();
    let ws = waitset().unwrap();
    let _guard = ws.attach_notification(&sub).unwrap();
    // Nothing there: the wait times out.
    let start = Instant::now();
    wait_any(&ws, Duration::ZERO, Duration::from_millis(30), &[&sub]).unwrap();
    assert!(start.elapsed() >= Duration::from_millis(25));
    assert!(!sub.has_samples().unwrap());
    let sender = {
        let name = name.clone();
        std::thread::spawn(move || {
            let link = Link::open(TransportKind::Uds, &format!("udstest-sender-{}", std::process::id())).unwrap();
            let publisher = Topic::<Measurement>::publisher(&link, &name).unwrap();
            std::thread::sleep(Duration::from_millis(20));
            publisher.send(&measurement(9, 9)).unwrap().subscribers
        })
    };
    let start = Instant::now();
    while !sub.has_samples().unwrap() && start.elapsed() < Duration::from_secs(10) {
        wait_any(&ws, Duration::ZERO, Duration::from_secs(1), &[&sub]).unwrap();
    }
    assert_eq!(sender.join().unwrap(), 1);
    let got = sub.receive_all().unwrap();
    assert_eq!(got.len(), 1);
    assert_eq!(got[0].header.step, 9);
    // The blocking single-topic wait works the same way.
    assert!(sub.wait(Duration::ZERO, Duration::from_millis(10)).unwrap().is_empty());
}

#[test]
fn socket_directories_are_private_to_the_user() {
    let link = link();
    let name = unique("private");
    let _sub = Topic::<Truth>::subscriber(&link, &name).unwrap();
    for dir in [uds::base_dir(), uds::topic_dir(&name)] {
        let mode = std::fs::metadata(&dir).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o700, "{}", dir.display());
    }
}

/// A topic directory created without its search bit — what a umask set for a moment by iceoryx2's
/// socket binding in another thread made of it — is set to 0700 and used, not left unusable.
#[test]
fn a_topic_directory_made_0600_by_a_racing_umask_is_set_to_0700() {
    let link = link();
    let name = unique("umask");
    let dir = uds::topic_dir(&name);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o600)).unwrap();
    let sub = Topic::<Truth>::subscriber(&link, &name).unwrap();
    assert_eq!(std::fs::metadata(&dir).unwrap().permissions().mode() & 0o777, 0o700);
    let publisher = Topic::<Truth>::publisher(&link, &name).unwrap();
    assert_eq!(publisher.send(&Truth::new(0, 1, [0.0, 0.0])).unwrap().subscribers, 1);
    drop(sub);
}

#[test]
fn iceoryx2_and_socket_topics_of_one_name_do_not_meet() {
    let uds_link = link();
    let iox_link = Link::open(TransportKind::Iceoryx2, &format!("udstest-iox-{}", std::process::id())).unwrap();
    let name = unique("separate");
    let sub = Topic::<Truth>::subscriber(&uds_link, &name).unwrap();
    let publisher = Topic::<Truth>::publisher(&iox_link, &name).unwrap();
    assert_eq!(publisher.send(&Truth::new(0, 1, [0.0, 0.0])).unwrap().subscribers, 0);
    assert!(sub.receive_all().unwrap().is_empty());
}

#[test]
fn a_datagram_is_in_hand_when_a_poll_took_it() {
    // The receive stamp of a batch is when its last message was taken from the socket: a poll that took
    // it (has_samples) is that moment, not the later receive.
    let link = link();
    let name = unique("in-hand");
    let sub = Topic::<Measurement>::subscriber(&link, &name).unwrap();
    let publisher = Topic::<Measurement>::publisher(&link, &name).unwrap();
    let published = publisher.send(&measurement(1, 1)).unwrap().published_ns;
    assert!(sub.has_samples().unwrap());
    let polled = now_ns();
    std::thread::sleep(Duration::from_millis(5));
    let (got, in_hand) = sub.receive_stamped().unwrap();
    assert_eq!(got.len(), 1);
    assert!(published <= in_hand && in_hand <= polled, "{published} ≤ {in_hand} ≤ {polled}");
    // A message received without a poll first is in hand during the receive; an empty batch is stamped
    // when the receive ran.
    let published = publisher.send(&measurement(2, 2)).unwrap().published_ns;
    std::thread::sleep(Duration::from_millis(5));
    let before = now_ns();
    let (got, in_hand) = sub.receive_stamped().unwrap();
    assert!(got.len() == 1 && published < before && before <= in_hand && in_hand <= now_ns());
    let (got, at) = sub.receive_stamped().unwrap();
    assert!(got.is_empty() && at >= in_hand);
}
