#!/usr/bin/env python3
"""Read the MAVLink bridge's swarm state (`<domain>/swarm`, `uavloc::SwarmState/v1`) with iceoryx2's
official Python bindings, as a receiver front end on aircraft would to time and place its arrivals.

Reads for --seconds and prints one JSON object: the number of states read, and per UAV its newest
position (plane and latitude/longitude), heading, link state and the age of its fix.

    python3 examples/python/read_swarm.py --domain lab1 --seconds 2
"""

import argparse
import json
import time

import iceoryx2 as iox2

import uavloc_messages as msg

LINKS = {0: "unknown", 1: "flying", 2: "not_guided", 3: "quiet"}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--domain", required=True)
    p.add_argument("--seconds", type=float, default=2.0)
    a = p.parse_args()
    msg.check_layout()
    iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
    node = iox2.NodeBuilder.new().name(iox2.NodeName.new(f"{a.domain}/swarm-reader")).create(iox2.ServiceType.Ipc)
    service = msg.open_topic(node, f"{a.domain}/swarm", msg.SwarmState)
    subscriber = service.subscriber_builder().buffer_size(msg.SUBSCRIBER_BUFFER).create()
    newest, count = None, 0
    deadline = time.monotonic() + a.seconds
    while time.monotonic() < deadline:
        while True:
            sample = subscriber.receive()
            if sample is None:
                break
            newest = msg.SwarmState.from_buffer_copy(sample.payload().contents)
            sample.delete()
            count += 1
        time.sleep(0.02)
    out = {"states": count, "uavs": []}
    if newest is not None:
        now = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        for i in range(newest.count):
            fix = newest.fix_ns[i]
            out["uavs"].append({
                "position": list(newest.positions[i]),
                "lat_lon_deg": list(newest.lat_lon_deg[i]),
                "heading": newest.headings[i],
                "link": LINKS.get(newest.link[i], "?"),
                "fix_age_s": (now - fix) * 1e-9 if fix else None,
            })
        out["step"] = newest.header.step
    print(json.dumps(out))


if __name__ == "__main__":
    main()
