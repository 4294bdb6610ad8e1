#!/usr/bin/python3
"""The simulated mill over the kernel's SocketCAN (vcan0, inside the VM):
three drive simulators, each its own process (cnc-cia402-sim), the
controller (cncd: CANopen master, CiA 402 layer, motion, task) running a
program on them, and python3-can (Debian) as an independent peer that
records every frame and checks the process-data timing: SYNC period, every
drive's TPDO answering each SYNC within the cycle, RPDOs before their SYNC,
statuswords of enabled drives following, heartbeats.

usage: three_drives.py BIN_DIR
"""
import json
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time

import can

HERE = os.path.dirname(os.path.abspath(__file__))
NODES = (1, 2, 3)
PERIOD = 0.010
FINAL = [12.5, 7.5, 0.0]

failures = []


def check(ok, what):
    print(("ok: " if ok else "FAILED: ") + what, flush=True)
    if not ok:
        failures.append(what)


def pct(values, p):
    s = sorted(values)
    return s[min(len(s) - 1, int(len(s) * p))] if s else float("nan")


def main():
    bindir = sys.argv[1]
    if not os.path.isdir("/dev/shm"):
        # The VM's /dev (devtmpfs) has no /dev/shm for the controller's
        # shared segment: make one (scripts/vm/run.sh mounts it only if the
        # folder exists).
        os.makedirs("/dev/shm", exist_ok=True)
        subprocess.run(["mount", "-t", "tmpfs", "tmpfs", "/dev/shm"], check=False)
    work = tempfile.mkdtemp()
    for f in ("mill.ini", "mill.hal", "program.ngc", "tool.tbl"):
        shutil.copy(os.path.join(HERE, f), work)
    ini = os.path.join(work, "mill.ini")
    env = dict(os.environ, CNC_INSTANCE="vm-cia402-%d" % os.getpid(), CNC_NO_REALTIME="1")

    bus = can.Bus(interface="socketcan", channel="vcan0", receive_own_messages=False)
    try:  # read after the run: a big receive buffer keeps every frame (root in the VM)
        bus.socket.setsockopt(socket.SOL_SOCKET, 33, 128 * 1024 * 1024)
    except (OSError, AttributeError) as e:
        print("note: cannot enlarge the receive buffer: %s" % e)

    sims = [subprocess.Popen([os.path.join(bindir, "cnc-cia402-sim"), "--ini", ini, "--nodes", str(n)],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
            for n in NODES]
    time.sleep(1.0)
    log = open(os.path.join(work, "cncd.log"), "w")
    cncd = subprocess.Popen([os.path.join(bindir, "cncd"), ini], stdout=log, stderr=subprocess.STDOUT, env=env)

    def cnc(*args, timeout=120):
        r = subprocess.run([os.path.join(bindir, "cnc"), "--timeout", str(timeout)] + list(args), env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        return r.returncode, r.stdout

    started = time.time()
    steps = [("wait-ready", ("wait-ready",), 90), ("estop-reset", ("estop-reset",), 30), ("on", ("on",), 30),
             ("home all", ("home", "all"), 180), ("mode auto", ("mode", "auto"), 30),
             ("open", ("open", os.path.join(work, "program.ngc")), 30), ("run", ("run",), 30),
             ("wait-program", ("wait-program",), 400)]
    ran = True
    for name, args, timeout in steps:
        rc, out = cnc(*args, timeout=timeout)
        check(rc == 0, "cnc %s (%.1f s)%s" % (name, time.time() - started, "" if rc == 0 else ": " + out.strip()[-300:]))
        if rc != 0:
            ran = False
            break
    rc, out = cnc("status", "--json")
    status = json.loads(out) if rc == 0 else {}
    rc, messages = cnc("messages")
    print(messages)
    if ran:
        pos = status.get("motion", {}).get("position", [None] * 3)[:3]
        check(all(p is not None and abs(p - f) < 1e-6 for p, f in zip(pos, FINAL)),
              "final position %s, expected %s" % (pos, FINAL))
    check(" error " not in messages, "no error on the message channel")
    check("x-axis: homed by the drive (method 34)" in messages, "X homed by its drive on the zero pulse")
    cnc("shutdown", timeout=30)
    cncd.wait(timeout=60)
    log.close()
    check(cncd.returncode == 0, "cncd stopped cleanly (exit status %s)" % cncd.returncode)
    for p in sims:
        p.terminate()
    for n, p in zip(NODES, sims):
        out, _ = p.communicate(timeout=30)
        print("--- simulator %d\n%s" % (n, out.strip()))
    if failures:
        print("--- controller log")
        print(open(os.path.join(work, "cncd.log")).read()[-4000:])

    frames = []
    while True:
        m = bus.recv(timeout=0.5)
        if m is None:
            break
        frames.append(m)
    bus.shutdown()
    check(len(frames) > 2000, "%d frames recorded" % len(frames))
    check(not any(m.is_error_frame or m.is_extended_id for m in frames), "no error or extended frames")

    syncs = [m.timestamp for m in frames if m.arbitration_id == 0x080]
    iv = [b - a for a, b in zip(syncs, syncs[1:])]
    if iv:
        print("SYNC: %d frames, interval min %.2f ms, median %.2f ms, p99 %.2f ms, max %.2f ms"
              % (len(syncs), min(iv) * 1e3, statistics.median(iv) * 1e3, pct(iv, 0.99) * 1e3, max(iv) * 1e3))
        check(0.8 * PERIOD < statistics.median(iv) < 1.5 * PERIOD,
              "median SYNC interval %.2f ms for 10 ms" % (statistics.median(iv) * 1e3))

    # Per node: each TPDO1 answers a SYNC (none without one since its last),
    # how late after its SYNC, and the RPDO1 of each cycle before its SYNC.
    for n in NODES:
        tpdo_first = next((m.timestamp for m in frames if m.arbitration_id == 0x180 + n), None)
        check(tpdo_first is not None, "node %d sends TPDO1 on 0x%03X" % (n, 0x180 + n))
        if tpdo_first is None:
            continue
        last_sync = None
        answered_sync = True
        unsolicited, late, within = 0, [], 0
        rpdo_since_sync, rpdo_before, syncs_after = False, 0, 0
        for m in frames:
            if m.arbitration_id == 0x080:
                if m.timestamp >= tpdo_first - PERIOD:
                    syncs_after += 1
                    rpdo_before += 1 if rpdo_since_sync else 0
                rpdo_since_sync = False
                last_sync = m.timestamp
                answered_sync = False
            elif m.arbitration_id == 0x200 + n:
                rpdo_since_sync = True
            elif m.arbitration_id == 0x180 + n:
                if last_sync is None or answered_sync:
                    unsolicited += 1
                else:
                    late.append(m.timestamp - last_sync)
                    within += 1 if m.timestamp - last_sync < PERIOD else 0
                answered_sync = True
        if not late:
            check(False, "node %d: no TPDO1 answered a SYNC" % n)
            continue
        print("node %d: %d TPDO1 for %d SYNCs; %d within the cycle; latency after the SYNC median %.3f ms, "
              "p99 %.3f ms, max %.3f ms; RPDO1 before %d SYNCs"
              % (n, len(late), syncs_after, within, statistics.median(late) * 1e3, pct(late, 0.99) * 1e3,
                 max(late) * 1e3, rpdo_before))
        check(unsolicited == 0, "node %d: every TPDO1 answers a SYNC (%d without one)" % (n, unsolicited))
        check(len(late) >= 0.9 * syncs_after, "node %d: a TPDO1 for (nearly) every SYNC: %d of %d"
              % (n, len(late), syncs_after))
        check(statistics.median(late) < PERIOD, "node %d: the median answer comes within the cycle" % n)
        check(rpdo_before >= 0.9 * syncs_after, "node %d: RPDO1 before its SYNC in %d of %d cycles"
              % (n, rpdo_before, syncs_after))
        tpdo = [m for m in frames if m.arbitration_id == 0x180 + n]
        check(all(m.dlc == 6 for m in tpdo), "node %d: TPDO1 carries statusword + position (6 bytes)" % n)
        following = [m for m in tpdo if (m.data[0] | m.data[1] << 8) & 0x106F == 0x1027]
        check(len(following) > 200, "node %d: %d TPDO1 of an enabled drive following its set-points (bit 12)"
              % (n, len(following)))
        positions = set(int.from_bytes(m.data[2:6], "little", signed=True) for m in following)
        check(len(positions) > 100, "node %d: the position moved (%d distinct values)" % (n, len(positions)))
        hb = [m.timestamp for m in frames if m.arbitration_id == 0x700 + n and m.data[0] == 0x05]
        if len(hb) > 5:
            med = statistics.median([b - a for a, b in zip(hb, hb[1:])])
            check(0.075 < med < 0.15, "node %d heartbeat every %.1f ms (100 configured)" % (n, med * 1e3))

    shutil.rmtree(work, ignore_errors=True)
    if failures:
        print("%d check(s) failed" % len(failures))
        sys.exit(1)
    print("all checks passed")


if __name__ == "__main__":
    main()
