#!/usr/bin/env python3
"""Independent MAVLink decoder for the controller role (pymavlink, common dialect).

Plays a minimal autopilot (system --system-id, component 1) on a pymavlink connection,
speaking MAVLink 2 or, with --mavlink 1, only MAVLink 1 (it decodes both): sends
HEARTBEAT at 1 Hz (armed / offboard as commanded), LOCAL_POSITION_NED and ATTITUDE at 50 Hz
(a crude vehicle that moves towards the last position setpoint while armed in offboard),
and answers every COMMAND_LONG with COMMAND_ACK (accepted, or denied for arming with
--refuse-arm).

--flavour px4 (the default): offboard is PX4 main mode 6 and the vehicle climbs on position
setpoints. --flavour ardupilot: an ArduPilot Copter (MAV_AUTOPILOT_ARDUPILOTMEGA), guided is
custom mode 4; armed in guided on the ground it ignores position targets until
MAV_CMD_NAV_TAKEOFF (param7 = height), and in land mode (9) it descends and disarms.

--signing-key-file F: MAVLink 2 signing with the key in F (64 hex digits, or a passphrase
whose SHA-256 is the key): everything sent is signed, unsigned frames are refused.

--gcs-noise: a ground station shares the link (HEARTBEATs of MAV_TYPE_GCS from system 255,
component 190, and a COMMAND_ACK of its own), which the controller must ignore.

Everything the controller sends is decoded with pymavlink. When --count
SET_POSITION_TARGET_LOCAL_NED messages arrived and both MAV_CMD_COMPONENT_ARM_DISARM and
MAV_CMD_DO_SET_MODE were seen (and, with --until-north N, a position setpoint at least N m
north arrived), or after --max-count setpoints, or when --timeout seconds passed, it prints ONE JSON line:

  counts       messages per type
  commands     sorted set of COMMAND_LONG command ids
  arm_params   param1 of every arm/disarm command
  mode_params  [param1, param2] of every set-mode command
  heartbeats   distinct [type, autopilot, src_system, src_component] of HEARTBEATs
  sources      distinct [src_system, src_component] of every message
  setpoints    one [x, y, z, vx, vy, vz, type_mask, coordinate_frame] per setpoint
               (non-finite numbers become null)
  mavlink1     messages that arrived as MAVLink 1
  setpoints_v1 setpoints that arrived as MAVLink 1
  last_setpoint_v1  whether the last setpoint arrived as MAVLink 1
  bad_data     undecodable chunks
  timed_out    true when --timeout ended the run
  command_targets  distinct [target_system, target_component] of every COMMAND_LONG
  takeoffs     param7 of every MAV_CMD_NAV_TAKEOFF
  max_up       the highest the vehicle climbed (m)
  landed_mode  whether land mode was commanded
  signed_in    messages received that were signed (and checked)
  unsigned_in  messages received unsigned (only counted without signing)
"""

import argparse
import hashlib
import json
import math
import os
import sys
import time

os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil  # noqa: E402

ARM_DISARM = 400
DO_SET_MODE = 176
NAV_TAKEOFF = 22
PX4_OFFBOARD = 6
PX4_POSCTL = 3
COPTER_GUIDED = 4
COPTER_LAND = 9


def finite_or_none(v):
    return v if isinstance(v, (int, float)) and math.isfinite(v) else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--listen", required=True, help="pymavlink URL, e.g. udpin:127.0.0.1:14600")
    ap.add_argument("--count", type=int, default=100, help="setpoints to collect")
    ap.add_argument("--timeout", type=float, default=60.0, help="give up after this (s)")
    ap.add_argument(
        "--until-north",
        type=float,
        default=None,
        help="also wait for a position setpoint at least this far north (m)",
    )
    ap.add_argument(
        "--max-count",
        type=int,
        default=None,
        help="stop after this many setpoints whatever else is missing (default 10 x --count)",
    )
    ap.add_argument(
        "--mavlink",
        type=int,
        choices=[1, 2],
        default=2,
        help="the framing this autopilot sends (it decodes both)",
    )
    ap.add_argument("--system-id", type=int, default=1, help="this autopilot's system id")
    ap.add_argument("--flavour", choices=["px4", "ardupilot"], default="px4")
    ap.add_argument("--refuse-arm", action="store_true", help="deny every arm command")
    ap.add_argument("--gcs-noise", action="store_true", help="a GCS shares the link")
    ap.add_argument("--signing-key-file", default=None, help="sign, and refuse unsigned")
    args = ap.parse_args()
    v1 = args.mavlink == 1
    ardu = args.flavour == "ardupilot"
    max_count = args.max_count if args.max_count is not None else 10 * args.count

    conn = mavutil.mavlink_connection(
        args.listen, source_system=args.system_id, source_component=1, dialect="common"
    )
    mav = conn.mav
    m = mavutil.mavlink
    if args.signing_key_file:
        text = open(args.signing_key_file).read().strip()
        try:
            key = bytes.fromhex(text) if len(text) == 64 else None
        except ValueError:
            key = None
        if key is None:
            key = hashlib.sha256(text.encode()).digest()
        conn.setup_signing(key, sign_outgoing=True, allow_unsigned_callback=None,
                           initial_timestamp=None, link_id=0)
    signed_in = 0
    unsigned_in = 0

    counts = {}
    commands = set()
    arm_params = []
    mode_params = []
    heartbeats = set()
    sources = set()
    setpoints = []
    bad_data = 0
    mavlink1 = 0
    setpoints_v1 = 0
    last_setpoint_v1 = False

    command_targets = set()
    takeoffs = []
    landed_mode = False
    took_off = False
    max_up = 0.0
    armed = False
    offboard = False
    pos = [0.0, 0.0, 0.0]  # NED
    vel = [0.0, 0.0, 0.0]
    yaw = 0.0
    target = None
    boot = time.monotonic()
    next_hb = boot
    next_tel = boot
    timed_out = False
    max_north = -math.inf

    while True:
        now = time.monotonic()
        if now - boot > args.timeout:
            timed_out = True
            break
        north_ok = args.until_north is None or max_north >= args.until_north
        if len(setpoints) >= args.count and {ARM_DISARM, DO_SET_MODE} <= commands and north_ok:
            break
        if len(setpoints) >= max_count:
            break
        ms = int((now - boot) * 1000)
        if now >= next_hb:
            next_hb = now + 1.0
            base = m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
            if armed:
                base |= m.MAV_MODE_FLAG_SAFETY_ARMED
            if ardu:
                custom = COPTER_LAND if landed_mode else (COPTER_GUIDED if offboard else 0)
            else:
                custom = (PX4_OFFBOARD if offboard else PX4_POSCTL) << 16
            mav.heartbeat_send(
                m.MAV_TYPE_QUADROTOR,
                m.MAV_AUTOPILOT_ARDUPILOTMEGA if ardu else m.MAV_AUTOPILOT_PX4,
                base,
                custom,
                m.MAV_STATE_ACTIVE if armed else m.MAV_STATE_STANDBY,
                force_mavlink1=v1,
            )
            if args.gcs_noise:
                mav.srcSystem, mav.srcComponent = 255, 190
                mav.heartbeat_send(
                    m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0, m.MAV_STATE_ACTIVE,
                    force_mavlink1=v1,
                )
                # an ACK that is not the autopilot's: must not count as a refusal
                mav.command_ack_send(ARM_DISARM, m.MAV_RESULT_DENIED, force_mavlink1=v1)
                mav.srcSystem, mav.srcComponent = args.system_id, 1
        if now >= next_tel:
            dt = 0.02
            next_tel = max(next_tel + dt, now)
            vel = [0.0, 0.0, 0.0]
            if ardu and landed_mode:
                # land mode: descend, disarm on the ground
                pos[2] = min(0.0, pos[2] + 1.0 * dt)
                vel = [0.0, 0.0, 1.0]
                if pos[2] >= 0.0:
                    armed, took_off = False, False
            elif ardu and armed and offboard and not took_off:
                pass  # guided on the ground: position targets wait for a take-off
            elif armed and offboard and target is not None:
                d = [target[i] - pos[i] for i in range(3)]
                n = math.sqrt(sum(x * x for x in d))
                if n > 1e-6:
                    step = min(n, 5.0 * dt)
                    vel = [d[i] / n * step / dt for i in range(3)]
                    pos = [pos[i] + d[i] / n * step for i in range(3)]
            max_up = max(max_up, -pos[2])
            mav.local_position_ned_send(
                ms, pos[0], pos[1], pos[2], vel[0], vel[1], vel[2], force_mavlink1=v1
            )
            mav.attitude_send(ms, 0.0, 0.0, yaw, 0.0, 0.0, 0.0, force_mavlink1=v1)

        msg = conn.recv_match(blocking=True, timeout=0.005)
        if msg is None:
            continue
        kind = msg.get_type()
        if kind == "BAD_DATA":
            bad_data += 1
            continue
        counts[kind] = counts.get(kind, 0) + 1
        if getattr(msg, "_signed", False):
            signed_in += 1
        else:
            unsigned_in += 1
        sources.add((msg.get_srcSystem(), msg.get_srcComponent()))
        buf = msg.get_msgbuf()
        is_v1 = bool(buf) and buf[0] != 0xFD
        if is_v1:
            mavlink1 += 1
        if kind == "HEARTBEAT":
            heartbeats.add((msg.type, msg.autopilot, msg.get_srcSystem(), msg.get_srcComponent()))
        elif kind == "COMMAND_LONG":
            commands.add(msg.command)
            command_targets.add((msg.target_system, msg.target_component))
            result = m.MAV_RESULT_ACCEPTED
            if msg.command == ARM_DISARM:
                arm_params.append(finite_or_none(msg.param1))
                if args.refuse_arm:
                    result = m.MAV_RESULT_DENIED
                else:
                    armed = msg.param1 > 0.5
            elif msg.command == DO_SET_MODE:
                mode_params.append([finite_or_none(msg.param1), finite_or_none(msg.param2)])
                mode = int(round(msg.param2))
                if ardu:
                    offboard = mode == COPTER_GUIDED
                    landed_mode = mode == COPTER_LAND
                else:
                    offboard = mode == PX4_OFFBOARD
            elif msg.command == NAV_TAKEOFF:
                takeoffs.append(finite_or_none(msg.param7))
                if ardu and armed and offboard and math.isfinite(msg.param7):
                    took_off = True
                    target = [pos[0], pos[1], -msg.param7]
                else:
                    result = m.MAV_RESULT_TEMPORARILY_REJECTED
            mav.command_ack_send(msg.command, result, force_mavlink1=v1)
        elif kind == "SET_POSITION_TARGET_LOCAL_NED":
            setpoints_v1 += int(is_v1)
            last_setpoint_v1 = is_v1
            row = [msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz]
            setpoints.append([finite_or_none(v) for v in row] + [msg.type_mask, msg.coordinate_frame])
            if all(finite_or_none(v) is not None for v in row[:3]) and (took_off or not ardu):
                target = row[:3]
                max_north = max(max_north, msg.x)
                yaw = msg.yaw if math.isfinite(msg.yaw) else yaw

    out = {
        "counts": counts,
        "commands": sorted(commands),
        "arm_params": arm_params,
        "mode_params": mode_params,
        "heartbeats": sorted(list(h) for h in heartbeats),
        "sources": sorted(list(s) for s in sources),
        "setpoints": setpoints,
        "mavlink1": mavlink1,
        "setpoints_v1": setpoints_v1,
        "last_setpoint_v1": last_setpoint_v1,
        "bad_data": bad_data,
        "timed_out": timed_out,
        "command_targets": sorted(list(t) for t in command_targets),
        "takeoffs": takeoffs,
        "max_up": max_up,
        "landed_mode": landed_mode,
        "signed_in": signed_in,
        "unsigned_in": unsigned_in,
    }
    sys.stdout.write(json.dumps(out) + "\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
