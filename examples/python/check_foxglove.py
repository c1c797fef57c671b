#!/usr/bin/env python3
"""Check the Foxglove channels of a uavloc MCAP recording against Foxglove's published JSON schemas.

Every message on a channel whose schema is Foxglove's (`foxglove.LocationFix`, `foxglove.GeoJSON`,
`foxglove.SceneUpdate`, `foxglove.FrameTransform`) is validated with `jsonschema` against the schema of
that name in SCHEMA_DIR (from the registry: examples/python/fetch_foxglove_schemas.sh), and the schema
the recording carries is compared with it. A GeoJSON message's string must itself be a GeoJSON
FeatureCollection. Prints one JSON object: per Foxglove topic its schema, message count, invalid count
and the first errors; the GeoJSON features of the last map layer; the last fix of each map topic.
Exit status 1 when any message is invalid or any carried schema differs from the registry's.

    python3 examples/python/check_foxglove.py run.mcap target/foxglove-schemas
"""

import json
import os
import sys

import jsonschema
from mcap.reader import make_reader


def main(path, schema_dir):
    registry = {}
    topics = {}
    last_layer = None
    last_fix = {}
    bad = False
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if not schema.name.startswith("foxglove."):
                continue
            name = schema.name.split(".", 1)[1]
            if name not in registry:
                with open(os.path.join(schema_dir, name + ".json")) as s:
                    published = json.load(s)
                registry[name] = (published, jsonschema.Draft7Validator(published))
            published, validator = registry[name]
            t = topics.setdefault(channel.topic, {
                "schema": schema.name, "count": 0, "invalid": 0, "errors": [],
                "schema_as_published": json.loads(schema.data) == published,
                "message_encoding": channel.message_encoding, "schema_encoding": schema.encoding,
            })
            bad |= not t["schema_as_published"]
            t["count"] += 1
            body = json.loads(message.data)
            errors = [e.message for e in validator.iter_errors(body)]
            if name == "GeoJSON" and not errors:
                layer = json.loads(body["geojson"])
                if layer.get("type") != "FeatureCollection" or not isinstance(layer.get("features"), list):
                    errors.append("the geojson string is not a FeatureCollection")
                last_layer = layer
            if name == "LocationFix" and not errors:
                last_fix[channel.topic] = body
            if errors:
                bad = True
                t["invalid"] += 1
                t["errors"] = (t["errors"] + errors)[:3]
    features = [
        {"name": ft["properties"]["name"], "type": ft["geometry"]["type"], "coordinates": ft["geometry"]["coordinates"]}
        for ft in (last_layer or {}).get("features", [])
    ]
    print(json.dumps({"topics": topics, "features": features, "last_fix": last_fix}))
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    main(sys.argv[1], sys.argv[2])
