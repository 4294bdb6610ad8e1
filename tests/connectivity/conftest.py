"""Shared fixtures of the connectivity tests: cncd on a copy of configs/sim
(as tests/system/cncd_on_copy.sh does), with its own instance and no
realtime. The build's folders come from the environment that CTest sets:
CNC_BIN (build/bin), CNC_CONFIG (configs/sim); PYTHONPATH has build/python.
"""

import os
import shutil
import subprocess
import tempfile
import time

import pytest

BIN = os.environ.get("CNC_BIN", "")
CONFIG = os.environ.get("CNC_CONFIG", "")

# A short program for the tests (the demo takes minutes).
PROGRAM = """(connectivity test program)
G21 G90 G54
G0 X20 Y10 Z-5
G1 X30 F1200
G1 Y20
G0 Z0
M2
"""


class Controller:
    def __init__(self, work, instance, process):
        self.work = work
        self.instance = instance
        self.process = process
        self.program = os.path.join(work, "test.ngc")

    def cli(self, *args, timeout=60, check=True):
        env = dict(os.environ, CNC_INSTANCE=self.instance)
        r = subprocess.run([os.path.join(BIN, "cnc"), *args], env=env, capture_output=True, text=True,
                           timeout=timeout)
        if check and r.returncode != 0:
            raise AssertionError(f"cnc {' '.join(args)}: {r.returncode}: {r.stderr}")
        return r

    def log(self):
        with open(os.path.join(self.work, "cncd.log"), encoding="utf-8", errors="replace") as f:
            return f.read()


def start_controller(name):
    if not BIN or not CONFIG:
        pytest.skip("CNC_BIN and CNC_CONFIG are not set (run through ctest)")
    work = tempfile.mkdtemp(prefix=f"cnc-{name}-test.")
    shutil.copytree(CONFIG, os.path.join(work, "sim"))
    instance = f"{name}test-{os.getpid()}"
    env = dict(os.environ, CNC_INSTANCE=instance, CNC_NO_REALTIME="1")
    log = open(os.path.join(work, "cncd.log"), "w")
    process = subprocess.Popen([os.path.join(BIN, "cncd"), os.path.join(work, "sim", "sim.ini")], env=env,
                               stdout=subprocess.DEVNULL, stderr=log)
    c = Controller(work, instance, process)
    with open(c.program, "w") as f:
        f.write(PROGRAM)
    r = c.cli("--timeout", "30", "wait-ready", check=False)
    if r.returncode != 0:
        stop_controller(c)
        raise AssertionError(f"cncd did not start: {r.stderr}\n{c.log()}")
    return c


def stop_controller(c):
    if c.process.poll() is None:
        c.process.terminate()
        try:
            c.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            c.process.kill()
            c.process.wait()
    shutil.rmtree(c.work, ignore_errors=True)


@pytest.fixture(scope="module")
def controller(request):
    c = start_controller(request.module.__name__.replace("test_", "").replace("_", "")[:10])
    yield c
    stop_controller(c)


def wait_for(predicate, timeout=30, what="condition"):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def power_up_and_home(c):
    """E-stop reset, machine on, home all: through the CLI."""
    c.cli("estop-reset")
    c.cli("on")
    c.cli("--timeout", "60", "home", "all")
