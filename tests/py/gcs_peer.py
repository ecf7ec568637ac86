#!/usr/bin/env python3
"""A ground station alone on a link (pymavlink): answers whoever talks to it with
HEARTBEATs of MAV_TYPE_GCS from system 255, component 190, at 5 Hz, until --timeout
seconds passed. No autopilot is on this link, so a controller must say it heard none.
Speaks MAVLink 2, or MAVLink 1 with --mavlink 1. With --damage-crc every frame goes out
with its checksum inverted (what a dialect with other CRC seeds, a wrong baud rate or a
damaged line delivers): a controller must say it heard frames that failed their CRC."""

import argparse
import os
import time

os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--listen", required=True, help="pymavlink URL, e.g. udpin:127.0.0.1:14600")
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--mavlink", type=int, choices=[1, 2], default=2)
    ap.add_argument("--as-autopilot", action="store_true",
                    help="send PX4 quadrotor HEARTBEATs from system 1 instead (still no answers)")
    ap.add_argument("--damage-crc", action="store_true",
                    help="invert the checksum of every frame sent")
    args = ap.parse_args()
    sysid, comp = (1, 1) if args.as_autopilot else (255, 190)
    conn = mavutil.mavlink_connection(args.listen, source_system=sysid,
                                      source_component=comp, dialect="common")
    m = mavutil.mavlink
    end = time.monotonic() + args.timeout
    next_hb = 0.0
    while time.monotonic() < end:
        conn.recv_match(blocking=True, timeout=0.05)
        now = time.monotonic()
        if now >= next_hb and getattr(conn, "clients", None):
            next_hb = now + 0.2
            if args.damage_crc:
                msg = m.MAVLink_heartbeat_message(m.MAV_TYPE_QUADROTOR, m.MAV_AUTOPILOT_PX4,
                                                  0, 0, m.MAV_STATE_STANDBY, 3)
                frame = bytearray(msg.pack(conn.mav, force_mavlink1=args.mavlink == 1))
                frame[-2] ^= 0xFF
                frame[-1] ^= 0xFF
                conn.write(bytes(frame))
            elif args.as_autopilot:
                conn.mav.heartbeat_send(m.MAV_TYPE_QUADROTOR, m.MAV_AUTOPILOT_PX4, 0, 0,
                                        m.MAV_STATE_STANDBY, force_mavlink1=args.mavlink == 1)
            else:
                conn.mav.heartbeat_send(m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0,
                                        m.MAV_STATE_ACTIVE, force_mavlink1=args.mavlink == 1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
