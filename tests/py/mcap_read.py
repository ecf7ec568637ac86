#!/usr/bin/env python3
"""Independent reader of AERIS flight recordings (the `mcap` package from PyPI).

Usage: mcap_read.py FILE [--layout LAYOUT.json] [--dump DIR]

Reads FILE as a stream of records from its start (no summary section needed, so a file
whose recorder was killed reads up to its last complete record) and prints one JSON object:

  {"complete": bool,          # the stream ended cleanly (footer and end magic read)
   "error": str | null,       # why reading stopped early, if it did
   "channels": {topic: {"message_encoding", "schema_name", "schema_encoding"}},
   "schemas_valid_json": bool,  # every jsonschema / aeris-layout schema parses as JSON
   "json_messages_valid": bool, # every json-encoded message parses as JSON
   "raw_sizes_ok": bool,        # every aeris-raw message is as long as its schema's size
                                # (an exact frame: its header's size plus its pixels)
   "counts": {topic: messages},
   "first_json": {topic: the first message decoded},
   "image_formats": {topic: sorted formats of its foxglove.CompressedImage messages},
   "images_ok": bool,         # every CompressedImage's data is base64 of a whole JPEG
                              # (FF D8 ... FF D9) or PNG (its signature), as its format says
   "layout_missing": [topics] # with --layout: topics the Foxglove layout shows that the
                              # recording lacks (image, 3D and plot panels)
  }

--dump DIR writes the first picture of each image topic to DIR/<topic with / as _>.<format>.
"""

import argparse
import base64
import json
import os
import struct
import sys

from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def picture_ok(fmt, data):
    if fmt == "jpeg":
        return data[:2] == b"\xff\xd8" and data[-2:] == b"\xff\xd9"
    if fmt == "png":
        return data[:8] == PNG_SIGNATURE
    return False


def exact_frame_ok(data, header_size):
    """An exact frame (TOPIC/frame): the FrameHeader (seq u64, capture_ns u64, width u32,
    height u32, camera_position 3 f32, camera_yaw f32, hfov f32, format u8) then the pixels."""
    if len(data) < header_size:
        return False
    width, height = struct.unpack_from("<II", data, 16)
    fmt = data[44]
    per_pixel = {1: 3, 2: 2}.get(fmt)
    return per_pixel is not None and len(data) == header_size + width * height * per_pixel


def layout_topics(layout):
    """Topics a Foxglove layout's image, 3D and plot panels read."""
    topics = set()
    for panel, config in layout.get("configById", {}).items():
        kind = panel.split("!")[0]
        if kind == "Image":
            topics.add(config["imageMode"]["imageTopic"])
        elif kind == "3D":
            topics.update(config.get("topics", {}).keys())
        elif kind in ("Plot", "StateTransitions"):
            for p in config.get("paths", []):
                topics.add(p["value"].split(".")[0])
    return topics


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--layout")
    ap.add_argument("--dump")
    args = ap.parse_args()
    path = args.file
    image_formats = {}
    images_ok = True
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
                        if ch["schema_name"].endswith("+pixels"):
                            # an exact frame: the header, then width x height pixels of
                            # its format (1: RGB8, 2: depth u16)
                            raw_ok = raw_ok and exact_frame_ok(record.data, layout["size"])
                        else:
                            raw_ok = raw_ok and len(record.data) == layout["size"]
                    if ch["message_encoding"] == "json":
                        try:
                            value = json.loads(record.data)
                        except ValueError:
                            messages_ok = False
                            continue
                        first.setdefault(topic, value)
                        if ch["schema_name"] == "foxglove.CompressedImage":
                            fmt = value.get("format")
                            data = base64.b64decode(value.get("data", ""))
                            images_ok = images_ok and picture_ok(fmt, data)
                            seen = image_formats.setdefault(topic, set())
                            if args.dump and not seen:
                                name = topic.replace("/", "_") + "." + str(fmt)
                                with open(os.path.join(args.dump, name), "wb") as out:
                                    out.write(data)
                            seen.add(fmt)
                elif isinstance(record, Footer):
                    complete = True
        except Exception as e:  # a truncated last record: stop there
            error = f"{type(e).__name__}: {e}"
    missing = []
    if args.layout:
        with open(args.layout) as f:
            wanted = layout_topics(json.load(f))
        recorded = {c["topic"] for c in channels.values()}
        missing = sorted(wanted - recorded)
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
                "image_formats": {t: sorted(v) for t, v in image_formats.items()},
                "images_ok": images_ok,
                "layout_missing": missing,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
