#!/usr/bin/env python3
"""Independent reader of AERIS flight recordings (the `mcap` package from PyPI).

Usage: mcap_read.py FILE

Reads FILE as a stream of records from its start (no summary section needed, so a file
whose recorder was killed reads up to its last complete record) and prints one JSON object:

  {"complete": bool,          # the stream ended cleanly (footer and end magic read)
   "error": str | null,       # why reading stopped early, if it did
   "channels": {topic: {"message_encoding", "schema_name", "schema_encoding"}},
   "schemas_valid_json": bool,  # every jsonschema / aeris-layout schema parses as JSON
   "json_messages_valid": bool, # every json-encoded message parses as JSON
   "raw_sizes_ok": bool,        # every aeris-raw message is as long as its schema's size
   "counts": {topic: messages},
   "first_json": {topic: the first message decoded}}
"""

import json
import sys

from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader


def main() -> int:
    path = sys.argv[1]
    schemas = {}
    channels = {}
    counts = {}
    first = {}
    schemas_ok = True
    raw_ok = True
    messages_ok = True
    complete = False
    error = None
    with open(path, "rb") as f:
        try:
            for record in StreamReader(f, skip_magic=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                    if record.encoding in ("jsonschema", "aeris-layout"):
                        try:
                            json.loads(record.data)
                        except ValueError:
                            schemas_ok = False
                elif isinstance(record, Channel):
                    schema = schemas.get(record.schema_id)
                    channels[record.id] = {
                        "topic": record.topic,
                        "schema_id": record.schema_id,
                        "message_encoding": record.message_encoding,
                        "schema_name": schema.name if schema else None,
                        "schema_encoding": schema.encoding if schema else None,
                    }
                elif isinstance(record, Message):
                    ch = channels[record.channel_id]
                    topic = ch["topic"]
                    counts[topic] = counts.get(topic, 0) + 1
                    if ch["message_encoding"] == "aeris-raw":
                        layout = json.loads(schemas[ch["schema_id"]].data)
                        raw_ok = raw_ok and len(record.data) == layout["size"]
                    if ch["message_encoding"] == "json":
                        try:
                            value = json.loads(record.data)
                        except ValueError:
                            messages_ok = False
                            continue
                        first.setdefault(topic, value)
                elif isinstance(record, Footer):
                    complete = True
        except Exception as e:  # a truncated last record: stop there
            error = f"{type(e).__name__}: {e}"
    by_topic = {
        c["topic"]: {k: v for k, v in c.items() if k not in ("topic", "schema_id")} for c in channels.values()
    }
    print(
        json.dumps(
            {
                "complete": complete,
                "error": error,
                "channels": by_topic,
                "schemas_valid_json": schemas_ok,
                "json_messages_valid": messages_ok,
                "raw_sizes_ok": raw_ok,
                "counts": counts,
                "first_json": {t: v for t, v in first.items() if not t.endswith("/image")},
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
