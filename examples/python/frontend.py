#!/usr/bin/env python3
"""An external uavloc front end in Python: a small world that publishes TDOA measurements and flies the
planner's commands, through iceoryx2's official Python bindings (`pip install iceoryx2==0.10.0`).

It stands where a receiver front end around an SDR would: uavloc's estimator, planner and monitor run
without emitter-sim (`uavloc launch --source external --domain D --steps N`), and this script

  1. opens D/measurement and D/command (and their companion event services, whose notifications wake
     the uavloc processes up) and waits until the estimator, the planner and the monitor are there;
  2. for k = 0..N: times the burst of the true emitter at each UAV (an arrival as a range, Gaussian range
     noise sigma per UAV, a common offset the receivers do not know), publishes the Measurement of step
     k — with --loss / --silence / --multipath, as a real receiver gives it: some arrivals lost, no burst
     at all, an arrival late by a reflection — and — except after the
     last step — waits for the Command of step k and flies it: each UAV goes to the command's waypoint
     with the command's heading (the planner computed where the heading leads after one interval);
  3. prints a JSON summary on stdout: the steps published, the commands flown, the true emitter, the
     final UAV positions, and the malformed messages it sent (--inject-bad).

The world is a scenario TOML of uavloc (default: scenarios/nominal.toml, the scenario `uavloc launch` runs
by default): `uavs`, `headings_deg` (omitted: each UAV heads at the emitter), `emitter`, `sigma`.

--loss P drops each arrival with probability P, --silence P makes the emitter silent at a step with
probability P (the step is still published, with every UAV's position, and still commanded),
--multipath P delays each arrival by a reflection of 200-1000 m with probability P.

--inject-bad publishes three malformed measurements before step 1 (a NaN range difference, a UAV count
of 2, a sequence number that steps back); uavloc's processes reject and count them, and the run goes on.

Options that break the contract on purpose, to see uavloc refuse it: --skip K never publishes step K (a
measurement lost on its way; the front end goes on to step K + 1, whose command never comes: uavloc's
monitor says which step it waits for), --remeasure K publishes step K a
second time with fresh noise (a different copy of a measured step: refused, `conflict`); --seq-start
sets the first sequence number (e.g. 18446744073709551615 from a second front end: refused as a second
source, it cannot make the first one's later measurements stale); --emitter X,Y moves the true emitter;
--step-delay-s waits before each measurement (a slow front end, so that another can join mid-run).

Exit codes: 0 done, 1 an error (a timeout waiting for uavloc, a malformed command), 2 bad arguments.
"""

import argparse
import ctypes
import json
import math
import os
import random
import sys
import time
import tomllib

import iceoryx2 as iox2

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import uavloc_messages as msg  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_SCENARIO = os.path.join(HERE, "..", "..", "scenarios", "nominal.toml")


class FrontEndError(Exception):
    pass


def load_world(path):
    with open(path, "rb") as f:
        sc = tomllib.load(f)
    uavs = [list(map(float, p)) for p in sc.get("uavs", [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]])]
    emitter = list(map(float, sc.get("emitter", [25000.0, 15000.0])))
    n = len(uavs)
    if not msg.MIN_UAVS <= n <= msg.MAX_UAVS:
        raise FrontEndError(f"{path}: {n} UAVs; uavloc takes {msg.MIN_UAVS} to {msg.MAX_UAVS}")
    sigma = sc.get("sigma", 28.7712)
    sigmas = [float(s) for s in sigma] if isinstance(sigma, list) else [float(sigma)] * n
    if "headings_deg" in sc:
        headings = [math.radians(float(h)) for h in sc["headings_deg"]]
    else:
        headings = [math.atan2(emitter[1] - u[1], emitter[0] - u[0]) for u in uavs]
    return uavs, headings, emitter, sigmas


def wait_until(what, predicate, timeout_s):
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise FrontEndError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(0.01)


class Link:
    """The front end's two topics: D/measurement (publisher + notifier), D/command (subscriber + listener)."""

    def __init__(self, domain):
        iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
        self.node = iox2.NodeBuilder.new().name(iox2.NodeName.new(f"{domain}/frontend")).create(iox2.ServiceType.Ipc)
        self.measurements = self._pubsub(f"{domain}/measurement", msg.Measurement)
        self.commands = self._pubsub(f"{domain}/command", msg.Command)
        self.publisher = self.measurements.publisher_builder().create()
        self.notifier = self._event(f"{domain}/measurement").notifier_builder().create()
        self.subscriber = self.commands.subscriber_builder().buffer_size(msg.SUBSCRIBER_BUFFER).create()
        self.listener = self._event(f"{domain}/command").listener_builder().create()

    def _pubsub(self, name, t):
        return msg.open_topic(self.node, name, t)

    def _event(self, name):
        return (
            self.node.service_builder(iox2.ServiceName.new(name))
            .event()
            .max_notifiers(msg.MAX_PUBLISHERS)
            .max_listeners(msg.MAX_SUBSCRIBERS)
            .event_id_max_value(msg.EVENT_ID_MAX)
            .notifier_created_event(iox2.EventId.new(msg.EVENT_PUBLISHER_CREATED))
            .notifier_dropped_event(iox2.EventId.new(msg.EVENT_PUBLISHER_DROPPED))
            .notifier_dead_event(iox2.EventId.new(msg.EVENT_PUBLISHER_DEAD))
            .open_or_create()
        )

    def wait_for_uavloc(self, timeout_s):
        # The estimator and the monitor subscribe to the measurements, the planner publishes the commands.
        wait_until(
            "uavloc's estimator and monitor (2 measurement subscribers) and planner (a command publisher)",
            lambda: self.measurements.dynamic_config.number_of_subscribers >= 2
            and self.commands.dynamic_config.number_of_publishers >= 1,
            timeout_s,
        )

    def linger(self, timeout_s):
        # A sample a subscriber has not read yet is lost when its publisher goes away: stay until uavloc's
        # planner has left the command topic (the launch has ended and recorded every step), at most
        # timeout_s.
        deadline = time.monotonic() + timeout_s
        while self.commands.dynamic_config.number_of_publishers > 0 and time.monotonic() < deadline:
            time.sleep(0.01)

    def publish(self, m):
        # The stamps of the latency chain (CLOCK_MONOTONIC, the clock of time.monotonic_ns on Linux).
        m.header.stamps.published_ns = m.header.stamps.measurement_published_ns = time.monotonic_ns()
        sample = self.publisher.loan_uninit()
        sample = sample.write_payload(m)
        sample.send()
        # Wake up the waiting uavloc processes (they block on the topic's event service).
        self.notifier.notify_with_custom_event_id(iox2.EventId.new(msg.EVENT_SAMPLE))

    def command_of(self, step, timeout_s):
        """The command of `step` (older ones are skipped) and when it was received."""
        deadline = time.monotonic() + timeout_s
        while True:
            while True:
                sample = self.subscriber.receive()
                if sample is None:
                    break
                c = msg.Command.from_buffer_copy(sample.payload().contents)
                received_ns = time.monotonic_ns()
                sample.delete()
                if c.header.step == step:
                    return c, received_ns
            left = deadline - time.monotonic()
            if left <= 0:
                raise FrontEndError(f"no command for step {step} within {timeout_s} s")
            self.listener.timed_wait(iox2.Duration.from_secs_f64(min(left, 0.1)))


def measure(step, seq, uavs, headings, emitter, sigmas, rng, impair=None):
    """The Measurement of step k: arrival a_i = r_i + n_i + offset, n_i ~ N(0, sigma_i^2), with an offset
    (the burst's unknown emission time) the receivers share. `impair` = (loss, silence, multipath)
    probabilities; returns the message and what happened: (silent, heard UAVs, reflected UAVs)."""
    loss, silence, multipath = impair or (0.0, 0.0, 0.0)
    n = len(uavs)
    offset = rng.uniform(0.0, 1.0e5)
    ranges = [math.hypot(u[0] - emitter[0], u[1] - emitter[1]) + rng.gauss(0.0, s) for u, s in zip(uavs, sigmas)]
    m = msg.Measurement()
    m.header.version = msg.MEASUREMENT_VERSION
    m.header.step = step
    m.header.seq = seq
    m.count = n
    silent = silence > 0.0 and rng.random() < silence
    heard, reflected = [], []
    for i in range(n):
        m.uavs[i][0], m.uavs[i][1] = uavs[i]
        m.sigmas[i] = sigmas[i]
        m.headings[i] = headings[i]
        if silent or (loss > 0.0 and rng.random() < loss):
            continue
        a = ranges[i] + offset
        if multipath > 0.0 and rng.random() < multipath:
            a += rng.uniform(200.0, 1000.0)
            reflected.append(i)
        m.arrivals[i] = a
        m.heard |= 1 << i
        heard.append(i)
    if silent:
        m.flags = msg.FLAG_SILENT
    return m, (silent, heard, reflected)


def fly(command, n):
    if command.count != n:
        raise FrontEndError(f"a command for {command.count} UAVs; this world has {n}")
    uavs = [[command.waypoints[i][0], command.waypoints[i][1]] for i in range(n)]
    headings = [command.headings[i] for i in range(n)]
    if not all(math.isfinite(v) for v in [*headings, *(c for u in uavs for c in u)]):
        raise FrontEndError(f"a command with non-finite headings or waypoints (step {command.header.step})")
    return uavs, headings


def bad_measurements(good, seq, last_accepted_seq):
    """Three malformed copies of `good`: a NaN arrival, 2 UAVs, a sequence number that steps back."""
    out = []
    nan = msg.Measurement.from_buffer_copy(good)
    nan.heard |= 1
    nan.arrivals[0] = float("nan")
    nan.header.seq = seq
    out.append(("nan", nan))
    two = msg.Measurement.from_buffer_copy(good)
    two.count = 2
    two.header.seq = seq + 1
    out.append(("count", two))
    stale = msg.Measurement.from_buffer_copy(good)
    stale.header.seq = last_accepted_seq
    out.append(("stale", stale))
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--domain", default=os.environ.get("UAVLOC_DOMAIN", "uavloc"), help="uavloc's --domain")
    p.add_argument("--steps", type=int, default=24, help="the launch's --steps N: steps 0..N are published")
    p.add_argument("--scenario", default=DEFAULT_SCENARIO, help="the world (a uavloc scenario TOML)")
    p.add_argument("--seed", type=int, default=7, help="seed of the range noise")
    p.add_argument("--timeout-s", type=float, default=30.0, help="how long to wait for uavloc and for a command")
    p.add_argument("--inject-bad", action="store_true", help="publish three malformed measurements before step 1")
    p.add_argument("--linger-s", type=float, default=10.0,
                   help="after the last step, stay (keeping the published measurements readable) until uavloc's "
                        "planner has left, at most this long")
    p.add_argument("--emitter", help="X,Y: the true emitter, m (default: the scenario's)")
    p.add_argument("--step-delay-s", type=float, default=0.0, help="wait this long before each measurement")
    p.add_argument("--remeasure", type=int, help="publish step K again, with fresh noise, after its first copy")
    p.add_argument("--skip", type=int, help="never publish step K: go on to step K + 1 without its command")
    p.add_argument("--seq-start", type=int, help="the first sequence number (default: the monotonic clock)")
    p.add_argument("--loss", type=float, default=0.0, help="probability that one UAV's arrival is lost")
    p.add_argument("--silence", type=float, default=0.0, help="probability that the emitter is silent at a step")
    p.add_argument("--multipath", type=float, default=0.0,
                   help="probability that an arrival is late by a reflection (200-1000 m)")
    args = p.parse_args()
    for name in ("loss", "silence", "multipath"):
        if not 0.0 <= getattr(args, name) < 1.0:
            p.error(f"--{name} must be a probability in [0, 1)")
    if args.steps < 0:
        p.error("--steps must be >= 0")
    if args.seq_start is not None and not 0 <= args.seq_start < 2**64:
        p.error("--seq-start must be a u64")

    msg.check_layout()
    uavs, headings, emitter, sigmas = load_world(args.scenario)
    if args.emitter:
        try:
            emitter = [float(v) for v in args.emitter.split(",")]
        except ValueError:
            p.error("--emitter takes X,Y in metres")
        if len(emitter) != 2:
            p.error("--emitter takes X,Y in metres")
    rng = random.Random(args.seed)
    link = Link(args.domain)
    link.wait_for_uavloc(args.timeout_s)
    # Sequence numbers start at the monotonic clock: a restarted front end numbers above its predecessor.
    seq = time.monotonic_ns() if args.seq_start is None else args.seq_start
    flown, held, bad_sent = 0, 0, []
    impair = (args.loss, args.silence, args.multipath)
    silent_steps, lost, reflected_total, partial_steps = 0, 0, 0, 0
    trigger = (0, 0)
    last_accepted = None
    for k in range(args.steps + 1):
        time.sleep(args.step_delay_s)
        m, (silent, heard, reflected) = measure(k, seq, uavs, headings, emitter, sigmas, rng, impair)
        silent_steps += silent
        lost += 0 if silent else len(uavs) - len(heard)
        partial_steps += (not silent) and len(heard) < len(uavs)
        reflected_total += len(reflected)
        m.header.stamps.trigger_command_published_ns, m.header.stamps.trigger_command_received_ns = trigger
        if args.inject_bad and k == 1:
            for kind, bad in bad_measurements(m, seq, last_accepted):
                link.publish(bad)
                bad_sent.append(kind)
            seq += 2
            m.header.seq = seq
        if args.skip != k:
            link.publish(m)
        last_accepted = seq
        seq = min(seq + 1, 2**64 - 1)
        if args.remeasure == k:
            again, _ = measure(k, seq, uavs, headings, emitter, sigmas, rng)
            again.header.stamps.trigger_command_published_ns, again.header.stamps.trigger_command_received_ns = trigger
            link.publish(again)
            bad_sent.append("remeasured")
            seq += 1
        if k == args.steps:
            break
        if args.skip == k:
            continue
        c, received_ns = link.command_of(k, args.timeout_s)
        uavs, headings = fly(c, len(uavs))
        flown += 1
        held += bool(c.flags & msg.COMMAND_FLAG_HOLD)
        trigger = (c.header.stamps.command_published_ns, received_ns)
    link.linger(args.linger_s)
    print(json.dumps({
        "domain": args.domain,
        "steps_published": args.steps + 1,
        "commands_flown": flown,
        "holds": held,
        "truth": emitter,
        "uavs": uavs,
        "bad_sent": bad_sent,
        "silent_steps": silent_steps,
        "partial_steps": partial_steps,
        "arrivals_lost": lost,
        "arrivals_reflected": reflected_total,
    }))


if __name__ == "__main__":
    try:
        main()
    except FrontEndError as e:
        print(f"frontend: error: {e}", file=sys.stderr)
        sys.exit(1)
