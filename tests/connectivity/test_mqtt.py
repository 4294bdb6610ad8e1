"""cnc-mqtt on the simulated mill with a real mosquitto broker on a
loopback port: retained state, positions, program events, alarms, the
last will, commands off by default, token and whitelist when on, and a
broker that goes away and comes back."""

import json
import os
import signal
import socket
import subprocess
import threading
import time

import pytest

from conftest import BIN, power_up_and_home, wait_for

PREFIX = "test/cnc"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Broker:
    def __init__(self, work):
        self.port = free_port()
        self.conf = os.path.join(work, "mosquitto.conf")
        with open(self.conf, "w") as f:
            f.write(f"listener {self.port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
        self.log = os.path.join(work, "mosquitto.log")
        self.p = None
        self.start()

    def start(self):
        self.p = subprocess.Popen([os.environ.get("CNC_MOSQUITTO") or "mosquitto", "-c", self.conf], stdout=subprocess.DEVNULL,
                                  stderr=open(self.log, "a"))
        def up():
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                return True
            except OSError:
                return False
        wait_for(up, timeout=10, what="mosquitto")

    def stop(self):
        self.p.terminate()
        self.p.wait(timeout=10)


class Subscriber:
    """mosquitto_sub in the background: every (topic, payload) it receives."""

    def __init__(self, broker, topic=PREFIX + "/#"):
        self.p = subprocess.Popen(["mosquitto_sub", "-h", "127.0.0.1", "-p", str(broker.port), "-t", topic, "-v"],
                                  stdout=subprocess.PIPE, text=True)
        self.messages = []
        self.t = threading.Thread(target=self._read, daemon=True)
        self.t.start()

    def _read(self):
        for line in self.p.stdout:
            topic, _, payload = line.rstrip("\n").partition(" ")
            self.messages.append((topic, payload))

    def on(self, sub):
        return [p for t, p in list(self.messages) if t == f"{PREFIX}/{sub}"]

    def close(self):
        self.p.terminate()
        self.p.wait(timeout=10)


def retained(broker, sub):
    r = subprocess.run(["mosquitto_sub", "-h", "127.0.0.1", "-p", str(broker.port), "-t", f"{PREFIX}/{sub}",
                        "-C", "1", "-W", "5", "--retained-only"], capture_output=True, text=True)
    return r.stdout.strip()


def publish(broker, sub, payload):
    subprocess.run(["mosquitto_pub", "-h", "127.0.0.1", "-p", str(broker.port), "-t", f"{PREFIX}/{sub}",
                    "-m", payload], check=True)


@pytest.fixture(scope="module")
def broker(controller):
    b = Broker(controller.work)
    yield b
    b.stop()


def start_bridge(controller, broker, *extra):
    env = dict(os.environ, CNC_INSTANCE=controller.instance)
    return subprocess.Popen([os.path.join(BIN, "cnc-mqtt"), "--port", str(broker.port), "--prefix", PREFIX,
                             "--rate", "5", *extra], env=env, stdout=subprocess.DEVNULL,
                            stderr=open(os.path.join(controller.work, "bridge.log"), "a"))


@pytest.fixture(scope="module")
def bridge(controller, broker):
    p = start_bridge(controller, broker)
    wait_for(lambda: retained(broker, "availability") == "online", what="online")
    yield p
    if p.poll() is None:
        p.terminate()
        p.wait(timeout=10)


def test_state_is_retained_and_the_bridge_is_online(broker, bridge):
    state = json.loads(retained(broker, "state"))
    assert state["task_state"] == "ESTOP" and state["estop"] is True
    assert retained(broker, "availability") == "online"


def test_positions_come_at_the_configured_rate(broker, bridge):
    sub = Subscriber(broker, PREFIX + "/position")
    time.sleep(2.5)
    sub.close()
    got = sub.on("position")
    assert 4 <= len(got) <= 40, f"{len(got)} position messages in 2.5 s at 5 per second"
    p = json.loads(got[-1])
    assert set(p["position"]) == {"X", "Y", "Z"} and set(p["actual_position"]) == {"X", "Y", "Z"}


def test_commands_are_ignored_unless_enabled(controller, broker, bridge):
    sub = Subscriber(broker)
    publish(broker, "command", json.dumps({"command": "estop-reset", "token": "x"}))
    time.sleep(1)
    sub.close()
    assert sub.on("command/result") == []
    assert "ESTOP" in controller.cli("status").stdout


def test_state_changes_program_events_and_alarms(controller, broker, bridge):
    sub = Subscriber(broker)
    power_up_and_home(controller)
    controller.cli("mode", "auto")
    controller.cli("open", controller.program)
    controller.cli("run")
    controller.cli("--timeout", "120", "wait-program")
    controller.cli("error", "coolant level low")
    wait_for(lambda: sub.on("alarm"), what="alarm")
    wait_for(lambda: any(json.loads(p)["event"] == "finished" for p in sub.on("program")), what="finished")
    sub.close()
    states = [json.loads(p)["task_state"] for p in sub.on("state")]
    # The bridge looks every 20 ms: the short E-stop-reset state between the
    # two CLI commands may fall between two looks.
    assert states[0] == "ESTOP" and states[-1] == "ON", states
    events = [json.loads(p)["event"] for p in sub.on("program")]
    assert events.index("started") < events.index("finished"), events
    assert "opened" in events
    alarm = json.loads(sub.on("alarm")[-1])
    assert alarm["text"] == "coolant level low" and alarm["source"] == "operator" and alarm["kind"] == "error"


def test_commands_need_the_token_and_the_whitelist(controller, broker, bridge):
    token = os.path.join(controller.work, "token")
    with open(token, "w") as f:
        f.write("s3cret\n")
    # Refused at the start: commands without a token file or a whitelist.
    r = subprocess.run([os.path.join(BIN, "cnc-mqtt"), "--commands", "--allow", "on"], capture_output=True, text=True)
    assert r.returncode == 2 and "--token-file" in r.stderr
    p = start_bridge(controller, broker, "--client-id", "commander", "--commands", "--token-file", token,
                     "--allow", "estop,estop-reset,on,mode")
    try:
        sub = Subscriber(broker, PREFIX + "/command/result")
        time.sleep(1)
        publish(broker, "command", json.dumps({"id": "a", "command": "estop", "token": "wrong"}))
        publish(broker, "command", json.dumps({"id": "b", "command": "home", "args": [-1], "token": "s3cret"}))
        publish(broker, "command", json.dumps({"id": "c", "command": "estop", "token": "s3cret"}))
        wait_for(lambda: len(sub.on("command/result")) >= 3, what="three results")
        res = {r["id"]: r for r in map(json.loads, sub.on("command/result"))}
        assert res["a"]["ok"] is False and "not authorised" in res["a"]["reason"]
        assert res["b"]["ok"] is False and "whitelist" in res["b"]["reason"]
        assert res["c"]["ok"] is True
        wait_for(lambda: json.loads(retained(broker, "state"))["task_state"] == "ESTOP", what="E-stop")
        publish(broker, "command", json.dumps({"id": "d", "command": "mode", "args": ["nonsense"], "token": "s3cret"}))
        wait_for(lambda: len(sub.on("command/result")) >= 4, what="fourth result")
        assert json.loads(sub.on("command/result")[-1])["ok"] is False
        sub.close()
    finally:
        p.terminate()
        p.wait(timeout=10)


def test_broker_restart_is_survived_and_the_controller_unaffected(controller, broker, bridge):
    broker.stop()
    time.sleep(1)
    assert controller.cli("ping").returncode == 0
    assert bridge.poll() is None
    broker.start()  # persistence off: the retained messages are gone with it
    wait_for(lambda: retained(broker, "availability") == "online", timeout=60, what="online again")
    wait_for(lambda: retained(broker, "state") != "", timeout=10, what="state again")


def test_last_will_says_offline_when_the_bridge_dies(broker, bridge):
    bridge.send_signal(signal.SIGKILL)
    bridge.wait(timeout=10)
    wait_for(lambda: retained(broker, "availability") == "offline", timeout=10, what="offline (last will)")
