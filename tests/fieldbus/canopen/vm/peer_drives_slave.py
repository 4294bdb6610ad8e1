#!/usr/bin/python3
"""python3-can (Debian) as an independent CANopen master on vcan0 driving our
slave stack (a cnc-canopen-node process built from echo_device.eds). The
protocol bytes here are written from CiA 301, not from our code: NMT and
boot-up, SDO expedited / segmented / block in both directions with the
CRC from Python's own binascii.crc_hqx (CRC-16-CCITT, init 0), abort codes,
PDO mapping over SDO, SYNC-synchronous PDOs, EMCY, node guarding, heartbeat.

usage: peer_drives_slave.py NODE_PROGRAM
"""
import binascii
import os
import statistics
import subprocess
import sys
import time

import can

HERE = os.path.dirname(os.path.abspath(__file__))
EDS = os.path.join(HERE, "..", "data", "echo_device.eds")
NODE = 7
failures = []


def check(ok, what):
    print(("ok: " if ok else "FAILED: ") + what)
    if not ok:
        failures.append(what)


def hexs(data):
    return " ".join("%02X" % b for b in data)


class Peer:
    def __init__(self):
        self.bus = can.Bus(interface="socketcan", channel="vcan0", receive_own_messages=False)
        self.stash = []  # frames received while waiting for another COB-ID

    def send(self, cob, data=b"", rtr=False):
        self.bus.send(can.Message(arbitration_id=cob, data=bytes(data), is_extended_id=False,
                                  is_remote_frame=rtr, dlc=len(data) if not rtr else 1))

    def recv(self, cob, timeout=2.0, want=None):
        def match(m):
            return m.arbitration_id == cob and not m.is_remote_frame and (want is None or want(m))
        for i, m in enumerate(self.stash):
            if match(m):
                return self.stash.pop(i)
        end = time.time() + timeout
        while time.time() < end:
            m = self.bus.recv(timeout=max(0.0, end - time.time()))
            if m is None:
                continue
            if match(m):
                return m
            self.stash = (self.stash + [m])[-1000:]
        return None

    def drain(self):
        self.stash = []
        while self.bus.recv(timeout=0.05) is not None:
            pass

    # --- SDO client, byte by byte from CiA 301 7.2.4.3 ---
    def sdo(self, data):
        self.send(0x600 + NODE, bytes(data).ljust(8, b"\0"))
        m = self.recv(0x580 + NODE)
        return bytes(m.data) if m else None

    @staticmethod
    def mux(index, sub):
        return bytes([index & 0xFF, index >> 8, sub])

    @staticmethod
    def abort_code(r):
        return int.from_bytes(r[4:8], "little") if r and r[0] == 0x80 else None

    def download_expedited(self, index, sub, value):
        n = len(value)
        return self.sdo(bytes([0x23 | ((4 - n) << 2)]) + self.mux(index, sub) + value)

    def upload(self, index, sub):
        r = self.sdo(bytes([0x40]) + self.mux(index, sub))
        if r is None or r[0] == 0x80:
            return r, None
        if r[0] & 0x02:  # expedited
            n = 4 - ((r[0] >> 2) & 3) if r[0] & 0x01 else 4
            return r, r[4:4 + n]
        size = int.from_bytes(r[4:8], "little")
        data, toggle = b"", 0
        while True:
            s = self.sdo(bytes([0x60 | (toggle << 4)]))
            if s is None or (s[0] & 0xE0) != 0x00 or ((s[0] >> 4) & 1) != toggle:
                return s, None
            n = 7 - ((s[0] >> 1) & 7)
            data += s[1:1 + n]
            if s[0] & 0x01:
                return r, data if len(data) == size else None
            toggle ^= 1

    def download_segmented(self, index, sub, data):
        r = self.sdo(bytes([0x21]) + self.mux(index, sub) + len(data).to_bytes(4, "little"))
        if r is None or r[0] != 0x60:
            return [r]
        answers, toggle, pos = [r], 0, 0
        while pos < len(data):
            chunk = data[pos:pos + 7]
            pos += len(chunk)
            last = pos >= len(data)
            s = self.sdo(bytes([(toggle << 4) | ((7 - len(chunk)) << 1) | (1 if last else 0)]) + chunk)
            answers.append(s)
            if s is None or s[0] != (0x20 | (toggle << 4)):
                break
            toggle ^= 1
        return answers

    def block_download(self, index, sub, data):
        r = self.sdo(bytes([0xC6]) + self.mux(index, sub) + len(data).to_bytes(4, "little"))
        if r is None or (r[0] & 0xE3) != 0xA0:
            return False, "initiate answered %s" % (hexs(r) if r else "nothing")
        server_crc = bool(r[0] & 0x04)
        blksize = r[4]
        pos = 0
        while pos < len(data):
            seq, start = 0, pos
            while seq < blksize and pos < len(data):
                chunk = data[pos:pos + 7]
                pos += len(chunk)
                seq += 1
                last = pos >= len(data)
                self.send(0x600 + NODE, bytes([(0x80 if last else 0) | seq]) + chunk.ljust(7, b"\0"))
            ack = self.recv(0x580 + NODE)
            if ack is None or ack.data[0] != 0xA2:
                return False, "no block acknowledgement"
            if ack.data[1] != seq:
                pos = start + 7 * ack.data[1]  # repeat after the last good segment
            blksize = ack.data[2]
        unused = (7 - len(data) % 7) % 7
        crc = binascii.crc_hqx(data, 0) if server_crc else 0
        e = self.sdo(bytes([0xC1 | (unused << 2)]) + crc.to_bytes(2, "little"))
        return e is not None and e[0] == 0xA1, "end answered %s" % (hexs(e) if e else "nothing")

    def block_upload(self, index, sub, blksize):
        r = self.sdo(bytes([0xA4]) + self.mux(index, sub) + bytes([blksize, 0]))
        if r is None or (r[0] & 0xE1) != 0xC0:
            return None, "initiate answered %s" % (hexs(r) if r else "nothing")
        size = int.from_bytes(r[4:8], "little") if r[0] & 0x02 else None
        crc_on = bool(r[0] & 0x04)
        self.send(0x600 + NODE, bytes([0xA3]).ljust(8, b"\0"))
        data, done = b"", False
        while not done:
            expected = 1
            while True:
                m = self.recv(0x580 + NODE)
                if m is None:
                    return None, "segment missing"
                seq, last = m.data[0] & 0x7F, bool(m.data[0] & 0x80)
                if seq == expected:
                    data += bytes(m.data[1:8])
                    expected += 1
                if seq == blksize or last:
                    break
            self.send(0x600 + NODE, bytes([0xA2, expected - 1, blksize]).ljust(8, b"\0"))
            done = last
        end = self.recv(0x580 + NODE)
        if end is None or (end.data[0] & 0xE3) != 0xC1:
            return None, "no end of block upload"
        unused = (end.data[0] >> 2) & 7
        data = data[:len(data) - unused]
        crc = int.from_bytes(end.data[1:3], "little")
        self.send(0x600 + NODE, bytes([0xA1]).ljust(8, b"\0"))
        if size is not None and len(data) != size:
            return None, "size %d, indicated %d" % (len(data), size)
        if crc_on and crc != binascii.crc_hqx(data, 0):
            return None, "CRC 0x%04X, computed 0x%04X" % (crc, binascii.crc_hqx(data, 0))
        return data, "crc 0x%04X" % crc


def main():
    node_prog = sys.argv[1]
    peer = Peer()
    node = subprocess.Popen([node_prog, "--interface", "socketcan:vcan0", "--node", str(NODE), "--eds", EDS,
                             "--echo", "0x607A:0=0x6064:0", "--quiet"])
    try:
        boot = peer.recv(0x700 + NODE, timeout=10)
        check(boot is not None and bytes(boot.data) == b"\x00", "boot-up message 0x%03X [00] at power-on" % (0x700 + NODE))

        # NMT reset communication -> boot-up again
        peer.send(0x000, bytes([0x82, NODE]))
        boot = peer.recv(0x700 + NODE, timeout=3)
        check(boot is not None and bytes(boot.data) == b"\x00", "NMT reset communication answered by a boot-up message")

        r = peer.sdo(bytes([0x40, 0x00, 0x10, 0x00]))
        check(r == bytes([0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]),
              "expedited upload of 0x1000: 43 00 10 00 92 01 02 00 (%s)" % (hexs(r) if r else "-"))
        r, v = peer.upload(0x1018, 1)
        check(v == (0xCC1).to_bytes(4, "little"), "vendor-ID 0x00000CC1 from 0x1018:01")
        r, v = peer.upload(0x1018, 4)
        check(v == (NODE + 0x1000).to_bytes(4, "little"), "serial number $NODEID+0x1000 from the EDS")

        r = peer.download_expedited(0x1017, 0, (50).to_bytes(2, "little"))
        check(r == bytes([0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0]), "expedited download 0x2B of 0x1017 answered 60 17 10 00")
        peer.drain()
        hb = []
        end = time.time() + 1.0
        while time.time() < end:
            m = peer.recv(0x700 + NODE, timeout=0.5)
            if m is not None:
                hb.append(m)
        check(len(hb) >= 8 and all(bytes(m.data) == b"\x7F" for m in hb), "heartbeat [7F] (pre-operational), %d in 1 s" % len(hb))
        if len(hb) > 3:
            med = statistics.median([b.timestamp - a.timestamp for a, b in zip(hb, hb[1:])])
            check(abs(med - 0.050) < 0.0125, "heartbeat period %.1f ms (0x1017 = 50)" % (med * 1e3))
        peer.download_expedited(0x1017, 0, (0).to_bytes(2, "little"))

        r, v = peer.upload(0x1008, 0)
        check(r is not None and r[0] == 0x41 and v == b"Echo device",
              "segmented upload of 0x1008 (0x41, size %s): %r" % (int.from_bytes(r[4:8], "little") if r else "-", v))

        payload = bytes(range(20))
        answers = peer.download_segmented(0x2001, 0, payload)
        check([a[0] if a else None for a in answers] == [0x60, 0x20, 0x30, 0x20],
              "segmented download: 0x60 then toggled 0x20 / 0x30 / 0x20 (%s)" % [hexs(a[:1]) if a else None for a in answers])
        r, v = peer.upload(0x2001, 0)
        check(v == payload, "segmented upload returns the 20 bytes")

        big = bytes((i * 37 + 11) & 0xFF for i in range(300))
        ok, why = peer.block_download(0x2001, 0, big)
        check(ok, "block download of 300 bytes with CRC (%s)" % why)
        data, why = peer.block_upload(0x2001, 0, 20)
        check(data == big, "block upload in sub-blocks of 20 segments, CRC checked with binascii.crc_hqx (%s)" % why)

        r = peer.sdo(bytes([0x40, 0x00, 0x30, 0x00]))
        check(Peer.abort_code(r) == 0x06020000 and r[1:4] == bytes([0x00, 0x30, 0x00]), "abort 0x06020000 for 0x3000 (%s)" % (hexs(r) if r else "-"))
        r = peer.download_expedited(0x1000, 0, (1).to_bytes(4, "little"))
        check(Peer.abort_code(r) == 0x06010002, "abort 0x06010002 writing read-only 0x1000")
        r = peer.sdo(bytes([0x21]) + Peer.mux(0x2001, 0) + (14).to_bytes(4, "little"))
        r = peer.sdo(bytes([0x10]) + bytes(7))
        check(Peer.abort_code(r) == 0x05030000, "abort 0x05030000 on a segment with the wrong toggle bit")
        r = peer.sdo(bytes([0xE0]) + Peer.mux(0x1000, 0))
        check(Peer.abort_code(r) == 0x05040001, "abort 0x05040001 for an unknown command specifier")
        r = peer.download_expedited(0x6060, 0, bytes([20]))
        check(Peer.abort_code(r) == 0x06090031, "abort 0x06090031 above HighLimit=10 of 0x6060")

        # PDO mapping over SDO: TPDO1 = statusword + position actual, every SYNC;
        # RPDO1 (EDS default: controlword + target) made synchronous.
        steps = [
            (0x1800, 1, (0x180 + NODE | 0x80000000).to_bytes(4, "little")),
            (0x1A00, 0, bytes([0])),
            (0x1A00, 1, (0x60410010).to_bytes(4, "little")),
            (0x1A00, 2, (0x60640020).to_bytes(4, "little")),
            (0x1A00, 0, bytes([2])),
            (0x1800, 2, bytes([1])),
            (0x1800, 1, (0x180 + NODE).to_bytes(4, "little")),
            (0x1400, 2, bytes([1])),
        ]
        for index, sub, value in steps:
            r = peer.download_expedited(index, sub, value)
            check(r is not None and r[0] == 0x60, "remap: 0x%04X:%02X = %s accepted" % (index, sub, hexs(value)))
        r = peer.download_expedited(0x1A00, 1, (0x60410010).to_bytes(4, "little"))
        check(Peer.abort_code(r) == 0x06010000, "remapping a valid TPDO is refused with 0x06010000")

        peer.send(0x000, bytes([0x01, NODE]))
        time.sleep(0.2)
        peer.drain()
        peer.send(0x200 + NODE, bytes([0x0F, 0x00]) + (12345).to_bytes(4, "little", signed=True))
        peer.send(0x080)
        t1 = peer.recv(0x180 + NODE)
        peer.send(0x080)
        t2 = peer.recv(0x180 + NODE)
        check(t1 is not None and len(t1.data) == 6 and bytes(t1.data[:2]) == bytes([0x50, 0x02]),
              "TPDO1 on 0x%03X after SYNC with the statusword (%s)" % (0x180 + NODE, hexs(t1.data) if t1 else "-"))
        check(t2 is not None and int.from_bytes(t2.data[2:6], "little", signed=True) == 12345,
              "the target applied at the first SYNC comes back at the second (%s)" % (hexs(t2.data) if t2 else "-"))
        r, v = peer.upload(0x6040, 0)
        check(v == bytes([0x0F, 0x00]), "RPDO1 wrote the controlword 0x000F")

        r = peer.download_expedited(0x2FFF, 0, (0x8611).to_bytes(2, "little"))
        e = peer.recv(0x080 + NODE)
        check(e is not None and len(e.data) == 8 and bytes(e.data[:2]) == bytes([0x11, 0x86]) and e.data[2] & 0x01,
              "EMCY 0x8611 on 0x%03X with the generic error bit (%s)" % (0x080 + NODE, hexs(e.data) if e else "-"))
        r, v = peer.upload(0x1003, 1)
        check(v is not None and int.from_bytes(v, "little") & 0xFFFF == 0x8611, "0x1003:01 holds the newest error")

        peer.drain()
        peer.send(0x700 + NODE, rtr=True)
        g1 = peer.recv(0x700 + NODE)
        peer.send(0x700 + NODE, rtr=True)
        g2 = peer.recv(0x700 + NODE)
        check(g1 is not None and g2 is not None and {g1.data[0], g2.data[0]} == {0x05, 0x85},
              "node guarding: state 0x05 with a toggling bit 7 (%s, %s)" % (hexs(g1.data) if g1 else "-", hexs(g2.data) if g2 else "-"))

        peer.send(0x000, bytes([0x02, NODE]))
        time.sleep(0.1)
        peer.drain()
        peer.send(0x600 + NODE, bytes([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]))
        check(peer.recv(0x580 + NODE, timeout=0.5) is None, "a stopped node answers no SDO")
        peer.send(0x000, bytes([0x80, NODE]))
        r = peer.sdo(bytes([0x40, 0x00, 0x10, 0x00]))
        check(r is not None and r[0] == 0x43, "back in pre-operational it answers again")
    finally:
        node.terminate()
        node.wait()
        peer.bus.shutdown()
    print("%d check(s) failed" % len(failures) if failures else "all checks passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
