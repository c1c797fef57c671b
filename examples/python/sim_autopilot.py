#!/usr/bin/env python3
"""A simulated fixed-wing autopilot that speaks real MAVLink 2 (pymavlink): the peer the uavloc bridge is
tested against, one process per UAV.

It flies the guided targets it is sent (SET_POSITION_TARGET_GLOBAL_INT to its system id): a constant
ground speed, turning towards the target at most at speed / r_min (a fixed-wing's turn-rate limit), in
simulated time that runs --time-scale times faster than the wall clock. It sends HEARTBEAT (fixed wing,
ArduPilot, armed, GUIDED) at 1 Hz of wall time, and GLOBAL_POSITION_INT and ATTITUDE at --rate-hz of wall
time. Until its first target it holds its start position (on the runway, armed).

Positions: the start is given in the run's plane (metres east/north of --origin, at the origin's
altitude); latitude/longitude come from pymap3d (WGS84 ENU), the same plane as uavloc's.

Faults, for the tests: --drop-at S --drop-for D (wall seconds after the first target: neither send nor
read for D s, flying on), --never-arm, --system-id-sent N (claims another system id), --nan-yaw (every
ATTITUDE's yaw is NaN), --offset-m M (reports its position M metres north of the truth).

    python3 examples/python/sim_autopilot.py --connect udpout:127.0.0.1:14550 --system-id 1 \\
        --origin 47.3977,8.5456,488 --start 1500,500 --heading-deg 57 --speed 50 --r-min 1000 --time-scale 20

Prints one JSON line when it stops (SIGTERM/SIGINT or --duration): its final state and counts.
"""

import argparse
import json
import math
import os
import signal
import sys
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
import pymap3d  # noqa: E402


def parse_pair(text):
    a, b = (float(v) for v in text.split(","))
    return a, b


class Plane:
    """The flat plane of the run: ENU east/north at the origin's altitude (as uavloc's model::geo)."""

    def __init__(self, lat0, lon0, h0):
        self.lat0, self.lon0, self.h0 = lat0, lon0, h0

    def to_geodetic(self, x, y):
        up = -(x * x + y * y) / (2 * 6_371_000.0)
        for _ in range(8):
            lat, lon, h = pymap3d.enu2geodetic(x, y, up, self.lat0, self.lon0, self.h0)
            if abs(h - self.h0) < 1e-9:
                break
            up -= h - self.h0
        return lat, lon

    def to_local(self, lat, lon):
        e, n, _ = pymap3d.geodetic2enu(lat, lon, self.h0, self.lat0, self.lon0, self.h0)
        return e, n


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--connect", required=True, help="pymavlink endpoint, e.g. udpout:127.0.0.1:14550")
    p.add_argument("--system-id", type=int, required=True)
    p.add_argument("--origin", required=True, help="LAT,LON,ALT of the run's plane")
    p.add_argument("--start", required=True, help="X,Y in metres in the plane")
    p.add_argument("--heading-deg", type=float, default=0.0, help="initial heading, degrees counter-clockwise from east")
    p.add_argument("--speed", type=float, default=50.0, help="ground speed, m/s")
    p.add_argument("--r-min", type=float, default=1000.0, help="smallest turn radius, metres")
    p.add_argument("--time-scale", type=float, default=1.0, help="simulated seconds per wall second")
    p.add_argument("--rate-hz", type=float, default=10.0, help="position and attitude reports per wall second")
    p.add_argument("--duration", type=float, default=0.0, help="stop after this many wall seconds (0: never)")
    p.add_argument("--drop-at", type=float, default=-1.0)
    p.add_argument("--drop-for", type=float, default=0.0)
    p.add_argument("--never-arm", action="store_true")
    p.add_argument("--system-id-sent", type=int, default=0)
    p.add_argument("--nan-yaw", action="store_true")
    p.add_argument("--offset-m", type=float, default=0.0)
    a = p.parse_args()

    lat0, lon0, h0 = (float(v) for v in a.origin.split(","))
    plane = Plane(lat0, lon0, h0)
    x, y = parse_pair(a.start)
    psi = math.radians(a.heading_deg)
    omega = a.speed / a.r_min
    sent_id = a.system_id_sent or a.system_id
    link = mavutil.mavlink_connection(a.connect, source_system=sent_id, source_component=1)
    link.mav.srcSystem = sent_id

    stop = {"now": False}
    signal.signal(signal.SIGTERM, lambda *_: stop.__setitem__("now", True))
    signal.signal(signal.SIGINT, lambda *_: stop.__setitem__("now", True))

    counts = {"targets": 0, "reports": 0, "other_targets": 0}
    target = None
    first_target_at = None
    started = time.monotonic()
    last = started
    next_report = started
    next_heartbeat = started
    boot = started
    base_mode = mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavutil.mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
    if not a.never_arm:
        base_mode |= mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED

    while not stop["now"]:
        now = time.monotonic()
        if a.duration and now - started > a.duration:
            break
        dropped = (
            first_target_at is not None
            and a.drop_at >= 0
            and a.drop_at <= now - first_target_at < a.drop_at + a.drop_for
        )
        # Read what came (during a drop it is lost: read and thrown away).
        while True:
            m = link.recv_match(blocking=False)
            if m is None:
                break
            if dropped or m.get_type() != "SET_POSITION_TARGET_GLOBAL_INT":
                continue
            if m.target_system != a.system_id:
                counts["other_targets"] += 1
                continue
            target = plane.to_local(m.lat_int * 1e-7, m.lon_int * 1e-7)
            counts["targets"] += 1
            if first_target_at is None:
                first_target_at = now
        # Fly: simulated time in small steps, turning towards the target at most at omega.
        sim_dt = (now - last) * a.time_scale
        last = now
        if target is not None:
            n = max(1, int(math.ceil(sim_dt / 0.05)))
            h = sim_dt / n
            for _ in range(n):
                want = math.atan2(target[1] - y, target[0] - x)
                turn = max(-omega * h, min(omega * h, wrap(want - psi)))
                psi = wrap(psi + turn)
                x += a.speed * h * math.cos(psi)
                y += a.speed * h * math.sin(psi)
        if not dropped and now >= next_heartbeat:
            next_heartbeat = now + 1.0
            link.mav.heartbeat_send(
                mavutil.mavlink.MAV_TYPE_FIXED_WING, mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, base_mode, 15,
                mavutil.mavlink.MAV_STATE_ACTIVE,
            )
        if not dropped and now >= next_report:
            next_report = now + 1.0 / a.rate_hz
            lat, lon = plane.to_geodetic(x, y + a.offset_m)
            course = (math.pi / 2 - psi) % (2 * math.pi)
            moving = target is not None
            vn = a.speed * math.sin(psi) if moving else 0.0
            ve = a.speed * math.cos(psi) if moving else 0.0
            ms = int((now - boot) * 1000) & 0xFFFFFFFF
            link.mav.global_position_int_send(
                ms, int(round(lat * 1e7)), int(round(lon * 1e7)), int((h0 + 120.0) * 1000), 120_000,
                int(round(vn * 100)), int(round(ve * 100)), 0, int(round(math.degrees(course) * 100)) % 36000,
            )
            yaw = float("nan") if a.nan_yaw else wrap(course)
            link.mav.attitude_send(ms, 0.0, 0.0, yaw, 0.0, 0.0, 0.0)
            counts["reports"] += 1
        time.sleep(0.005)
    print(json.dumps({"system_id": a.system_id, "x": x, "y": y, "heading": psi, **counts}), flush=True)


if __name__ == "__main__":
    sys.exit(main())
