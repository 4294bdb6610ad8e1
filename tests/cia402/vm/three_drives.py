#!/usr/bin/python3
"""The simulated mill over the kernel's SocketCAN (vcan0, inside the VM):
three drive simulators, each its own process (cnc-cia402-sim), the
controller (cncd: CANopen master, CiA 402 layer, motion, task) running a
program on them, and python3-can (Debian) as an independent peer that
records every frame and checks the process data against the cycle P
([EMCMOT]SERVO_PERIOD of mill.ini, which is also the SYNC period):

  - SYNC: the median interval is within 0.9 P .. 1.25 P (an emulated
    guest on a loaded host sends late at times; the tail is reported);
  - each drive answers the SYNCs after its NMT start with TPDO1, in order
    (never more answers than SYNCs), at least 98 % of them, the median
    answer within P / 2 of its SYNC;
  - the master sends each drive's RPDO1 before (nearly) every SYNC;
  - TPDO1 is statusword + position; enabled drives follow (bit 12) and
    move, and no drive's position ever leaves the range of the targets the
    master sent by more than 0.5 mm (a drive that runs away fails here);
  - heartbeats every 100 ms (median within 75..150 ms).

Then the controller's side: the program ends at its last point, no error
on the message channel, X homed by its drive on the zero pulse, cncd exits
with status 0.

usage: three_drives.py BIN_DIR
"""
import configparser
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
FINAL = [12.5, 7.5, 0.0]
COUNTS_PER_MM = 2000.0  # ENCODER_COUNTS 10000 / SCREW_LEAD 5 in mill.ini

failures = []


def check(ok, what):
    print(("ok: " if ok else "FAILED: ") + what, flush=True)
    if not ok:
        failures.append(what)


def pct(values, p):
    s = sorted(values)
    return s[min(len(s) - 1, int(len(s) * p))] if s else float("nan")


def period_s():
    ini = configparser.ConfigParser(strict=False, inline_comment_prefixes=("#", ";"))
    ini.read(os.path.join(HERE, "mill.ini"))
    return int(ini["EMCMOT"]["SERVO_PERIOD"]) * 1e-9


def run_machine(bindir, work, env):
    """Simulators and controller; returns (controller checks ran, simulator logs)."""
    ini = os.path.join(work, "mill.ini")
    sims = [subprocess.Popen([os.path.join(bindir, "cnc-cia402-sim"), "--ini", ini, "--nodes", str(n),
                              "--status-ms", "1000"],
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
    # "on" is answered once every drive follows (joint.N.amp-ready-in), so
    # homing goes right after it.
    steps = [("wait-ready", ("wait-ready",), 90), ("estop-reset", ("estop-reset",), 30), ("on", ("on",), 60),
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
    try:
        cncd.wait(timeout=60)
    except subprocess.TimeoutExpired:
        cncd.kill()
        cncd.wait()
    log.close()
    check(cncd.returncode == 0, "cncd stopped cleanly (exit status %s)" % cncd.returncode)
    for p in sims:
        p.terminate()
    sim_logs = []
    for n, p in zip(NODES, sims):
        out, _ = p.communicate(timeout=30)
        sim_logs.append("--- simulator %d\n%s" % (n, out.strip()))
    return sim_logs


def check_frames(frames, period):
    check(len(frames) > 2000, "%d frames recorded" % len(frames))
    check(not any(m.is_error_frame or m.is_extended_id for m in frames), "no error or extended frames")

    syncs = [m.timestamp for m in frames if m.arbitration_id == 0x080]
    iv = [b - a for a, b in zip(syncs, syncs[1:])]
    if not iv:
        check(False, "SYNCs on the bus")
        return
    med = statistics.median(iv)
    print("SYNC: %d frames, interval min %.2f ms, median %.2f ms, p99 %.2f ms, max %.2f ms (P = %.0f ms)"
          % (len(syncs), min(iv) * 1e3, med * 1e3, pct(iv, 0.99) * 1e3, max(iv) * 1e3, period * 1e3))
    check(0.9 * period <= med <= 1.25 * period,
          "median SYNC interval %.2f ms within 0.9 P .. 1.25 P (P = %.0f ms)" % (med * 1e3, period * 1e3))

    targets = {n: [] for n in NODES}
    for n in NODES:
        tpdo = [m for m in frames if m.arbitration_id == 0x180 + n]
        check(len(tpdo) > 0, "node %d sends TPDO1 on 0x%03X" % (n, 0x180 + n))
        if not tpdo:
            continue
        # Each TPDO1 answers the oldest SYNC not answered yet (a drive that
        # was late answers several at once, in order); SYNCs count from the
        # master's NMT start of the node (0x000: 01 <node> or 01 00).
        first = tpdo[0].timestamp
        starts = [m.timestamp for m in frames if m.arbitration_id == 0x000 and len(m.data) >= 2 and m.data[0] == 0x01
                  and m.data[1] in (0, n) and m.timestamp < first]
        check(bool(starts), "node %d: started by the master (NMT start) before its first TPDO1" % n)
        start = starts[-1] if starts else first
        pending, latencies, extra = [], [], 0
        rpdo_since_sync, rpdo_before, sync_count = False, 0, 0
        last_sync = None
        for m in frames:
            if m.arbitration_id == 0x080:
                last_sync = m.timestamp
                if m.timestamp >= start:
                    sync_count += 1
                    pending.append(m.timestamp)
                    rpdo_before += 1 if rpdo_since_sync else 0
                rpdo_since_sync = False
            elif m.arbitration_id == 0x200 + n:
                rpdo_since_sync = True
                if len(m.data) >= 6:
                    targets[n].append(int.from_bytes(m.data[2:6], "little", signed=True))
            elif m.arbitration_id == 0x180 + n:
                if pending:
                    latencies.append(m.timestamp - pending.pop(0))
                else:
                    extra += 1
        unanswered = len(pending)
        print("node %d: %d SYNCs, %d TPDO1 answers, %d unanswered at the end; answer after its SYNC: median %.3f ms, "
              "p99 %.3f ms, max %.3f ms; RPDO1 before %d SYNCs"
              % (n, sync_count, len(latencies), unanswered, statistics.median(latencies) * 1e3 if latencies else -1,
                 pct(latencies, 0.99) * 1e3, max(latencies, default=0) * 1e3, rpdo_before))
        check(extra == 0, "node %d: never more TPDO1 than SYNCs (%d extra)" % (n, extra))
        check(len(latencies) >= 0.98 * sync_count,
              "node %d: TPDO1 answers %d of %d SYNCs (at least 98 %%)" % (n, len(latencies), sync_count))
        if latencies:
            check(statistics.median(latencies) <= period / 2,
                  "node %d: median answer %.3f ms after its SYNC, within P / 2" % (n, statistics.median(latencies) * 1e3))
        check(rpdo_before >= 0.98 * sync_count, "node %d: RPDO1 before its SYNC in %d of %d cycles (at least 98 %%)"
              % (n, rpdo_before, sync_count))
        check(all(m.dlc == 6 for m in tpdo), "node %d: TPDO1 carries statusword + position (6 bytes)" % n)
        following = [m for m in tpdo if (m.data[0] | m.data[1] << 8) & 0x106F == 0x1027]
        check(len(following) > 200, "node %d: %d TPDO1 of an enabled drive following its set-points (bit 12)"
              % (n, len(following)))
        positions = [int.from_bytes(m.data[2:6], "little", signed=True) for m in following]
        check(len(set(positions)) > 50, "node %d: the position moved (%d distinct values)" % (n, len(set(positions))))
        if targets[n] and positions:
            lo, hi = min(targets[n]), max(targets[n])
            worst = max(max(lo - p, p - hi, 0) for p in positions) / COUNTS_PER_MM
            check(worst <= 0.5, "node %d: positions within 0.5 mm of the targets' range %.3f..%.3f mm (worst %.3f mm "
                  "outside)" % (n, lo / COUNTS_PER_MM, hi / COUNTS_PER_MM, worst))
        hb = [m.timestamp for m in frames if m.arbitration_id == 0x700 + n and m.data[0] == 0x05]
        if len(hb) > 5:
            med = statistics.median([b - a for a, b in zip(hb, hb[1:])])
            check(0.075 < med < 0.15, "node %d heartbeat every %.1f ms (100 configured)" % (n, med * 1e3))


def main():
    bindir = sys.argv[1]
    period = period_s()
    if not os.path.isdir("/dev/shm"):
        # The VM's /dev (devtmpfs) has no /dev/shm for the controller's
        # shared segment: make one (scripts/vm/run.sh mounts it only if the
        # folder exists).
        os.makedirs("/dev/shm", exist_ok=True)
        subprocess.run(["mount", "-t", "tmpfs", "tmpfs", "/dev/shm"], check=False)
    work = tempfile.mkdtemp()
    for f in ("mill.ini", "mill.hal", "program.ngc", "tool.tbl"):
        shutil.copy(os.path.join(HERE, f), work)
    env = dict(os.environ, CNC_INSTANCE="vm-cia402-%d" % os.getpid(), CNC_NO_REALTIME="1")

    bus = can.Bus(interface="socketcan", channel="vcan0", receive_own_messages=False)
    try:  # read after the run: a big receive buffer keeps every frame (root in the VM)
        bus.socket.setsockopt(socket.SOL_SOCKET, 33, 128 * 1024 * 1024)
    except (OSError, AttributeError) as e:
        print("note: cannot enlarge the receive buffer: %s" % e)

    sim_logs = run_machine(bindir, work, env)

    frames = []
    while True:
        m = bus.recv(timeout=0.5)
        if m is None:
            break
        frames.append(m)
    bus.shutdown()
    # The kernel stamps frames on reception; with two virtual CPUs frames from
    # different senders may reach this socket out of that order.
    frames.sort(key=lambda m: m.timestamp)
    check_frames(frames, period)

    if failures:
        print("\n".join(sim_logs))
        print("--- controller log")
        print(open(os.path.join(work, "cncd.log")).read()[-4000:])
    shutil.rmtree(work, ignore_errors=True)
    if failures:
        print("%d check(s) failed" % len(failures))
        sys.exit(1)
    print("all checks passed")


if __name__ == "__main__":
    main()
