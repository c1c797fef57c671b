#!/usr/bin/env python3
"""Summarise a uavloc MCAP recording (`uavloc launch --record run.mcap`) with the `mcap` package alone —
no uavloc needed: the channels are JSON with JSON schemas.

Prints one JSON object: the run's metadata, per channel its schema name and encodings, message count and
number of distinct steps (a step the pipeline published again — a retry or a replay after a crash — is
recorded again, as it went over the wire), and the recorded estimates per step (the first one of each step).

    python3 examples/python/read_recording.py run.mcap
"""

import json
import sys

from mcap.reader import make_reader


def main(path):
    channels = {}
    estimates = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        for schema, channel, message in reader.iter_messages():
            c = channels.setdefault(channel.topic, {
                "schema": schema.name,
                "schema_encoding": schema.encoding,
                "message_encoding": channel.message_encoding,
                "count": 0,
                "steps": set(),
            })
            c["count"] += 1
            body = json.loads(message.data)
            if isinstance(body, dict) and isinstance(body.get("step"), int):
                c["steps"].add(body["step"])
            if channel.topic == "/estimate":
                estimates.setdefault(str(body["step"]), {"position": body["position"], "status": body["status"]})
    for c in channels.values():
        c["steps"] = len(c["steps"])
    print(json.dumps({"metadata": metadata, "channels": channels, "estimates": estimates}))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    main(sys.argv[1])
