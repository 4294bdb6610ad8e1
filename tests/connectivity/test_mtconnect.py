"""cnc-mtconnect on the simulated mill: every endpoint over HTTP, the XML
against the MTConnect 1.3 schemas shipped here (mtconnect_schema/, the
official XSD 1.0 variants), sequence numbers across a running program."""

import os
import re
import subprocess
import time
import urllib.error
import urllib.request
import xml.etree.ElementTree as ET

import pytest

from conftest import BIN, power_up_and_home, wait_for

SCHEMAS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "mtconnect_schema")
NS = {"s": "urn:mtconnect.org:MTConnectStreams:1.3", "d": "urn:mtconnect.org:MTConnectDevices:1.3",
      "e": "urn:mtconnect.org:MTConnectError:1.3"}


@pytest.fixture(scope="module")
def agent(controller):
    env = dict(os.environ, CNC_INSTANCE=controller.instance)
    p = subprocess.Popen([os.path.join(BIN, "cnc-mtconnect"), "--port", "0", "--rate", "20"], env=env,
                         stdout=subprocess.PIPE, stderr=open(os.path.join(controller.work, "agent.log"), "w"),
                         text=True)
    line = p.stdout.readline()
    m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
    assert m, f"agent did not say where it listens: {line!r}"
    yield f"http://127.0.0.1:{m.group(1)}"
    p.terminate()
    p.wait(timeout=10)


def get(url):
    try:
        with urllib.request.urlopen(url, timeout=10) as r:
            return r.status, r.read().decode()
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode()


def valid(xml, part, tmp_path):
    f = tmp_path / f"{part}-{time.monotonic_ns()}.xml"
    f.write_text(xml)
    r = subprocess.run(["xmllint", "--noout", "--schema", os.path.join(SCHEMAS, f"MTConnect{part}_1.3_1.0.xsd"),
                        str(f)], capture_output=True, text=True)
    assert r.returncode == 0, f"{part} document not valid:\n{r.stderr}\n{xml[:3000]}"
    return ET.fromstring(xml)


def observations(root):
    """(sequence, element name, dataItemId, text) of a Streams document, by sequence."""
    out = []
    for el in root.iter():
        if "sequence" in el.attrib and "dataItemId" in el.attrib:
            out.append((int(el.attrib["sequence"]), el.tag.split("}")[1], el.attrib["dataItemId"], el.text or ""))
    return sorted(out)


def current_values(agent, tmp_path):
    root = valid(get(agent + "/current")[1], "Streams", tmp_path)
    return {o[2]: (o[1], o[3]) for o in observations(root)}


def test_probe_describes_the_machine(agent, tmp_path):
    status, xml = get(agent + "/probe")
    assert status == 200
    root = valid(xml, "Devices", tmp_path)
    ids = {d.attrib["id"] for d in root.iter("{%s}DataItem" % NS["d"])}
    assert {"avail", "estop", "mode", "system", "execution", "program", "line", "path_feedrate", "feed_ovr",
            "x_pos", "y_pos", "z_pos", "x_load", "s_speed", "s_load", "logic"} <= ids
    assert root.find(".//d:Controller/d:Components/d:Path", NS) is not None
    assert len(root.findall(".//d:Axes/d:Components/d:Linear", NS)) == 3


def test_current_shows_the_controller_in_estop(agent, tmp_path):
    wait_for(lambda: current_values(agent, tmp_path)["avail"][1] == "AVAILABLE", what="availability")
    v = current_values(agent, tmp_path)
    assert v["estop"] == ("EmergencyStop", "TRIGGERED")
    assert v["execution"] == ("Execution", "STOPPED")
    assert v["mode"][1] == "MANUAL"
    assert v["system"][0] == "Normal"
    assert v["x_pos"][0] == "Position"


def test_sample_from_and_count(agent, tmp_path):
    status, xml = get(agent + "/sample?from=1&count=5")
    root = valid(xml, "Streams", tmp_path)
    assert status == 200
    seqs = [o[0] for o in observations(root)]
    assert seqs == [1, 2, 3, 4, 5]
    header = root.find("s:Header", NS).attrib
    assert header["nextSequence"] == "6"
    assert int(header["firstSequence"]) == 1 and int(header["lastSequence"]) >= 5


def test_sample_out_of_range_is_an_mtconnect_error(agent, tmp_path):
    status, xml = get(agent + "/sample?from=999999999")
    assert status == 400
    root = valid(xml, "Error", tmp_path)
    assert root.find(".//e:Error", NS).attrib["errorCode"] == "OUT_OF_RANGE"
    status, xml = get(agent + "/sample?count=abc")
    assert status == 400
    valid(xml, "Error", tmp_path)


def test_unknown_request_is_an_mtconnect_error(agent, tmp_path):
    status, xml = get(agent + "/nothing-here")
    assert status == 404
    root = valid(xml, "Error", tmp_path)
    assert root.find(".//e:Error", NS).attrib["errorCode"] == "UNSUPPORTED"


def test_assets_is_an_empty_assets_document(agent, tmp_path):
    status, xml = get(agent + "/assets")
    assert status == 200
    valid(xml, "Assets", tmp_path)


def test_an_error_message_is_a_fault_until_estop_reset(controller, agent, tmp_path):
    controller.cli("error", "spindle drive overheated")
    wait_for(lambda: current_values(agent, tmp_path)["system"][0] == "Fault", what="Fault")
    assert current_values(agent, tmp_path)["system"][1] == "spindle drive overheated"
    controller.cli("estop-reset")
    wait_for(lambda: current_values(agent, tmp_path)["system"][0] == "Normal", what="Normal after E-stop reset")
    assert current_values(agent, tmp_path)["estop"][1] == "ARMED"


def test_sequence_numbers_across_a_running_program(controller, agent, tmp_path):
    power_up_and_home(controller)
    controller.cli("mode", "auto")
    controller.cli("open", controller.program)
    root = valid(get(agent + "/current")[1], "Streams", tmp_path)
    start = int(root.find("s:Header", NS).attrib["nextSequence"])
    controller.cli("run")
    controller.cli("--timeout", "120", "wait-program")
    time.sleep(0.3)  # a few samples after the end
    obs = []
    seq = start
    while True:  # read the whole run in pages of 200
        root = valid(get(agent + f"/sample?from={seq}&count=200")[1], "Streams", tmp_path)
        page = observations(root)
        obs += page
        nxt = int(root.find("s:Header", NS).attrib["nextSequence"])
        if not page or nxt == seq:
            break
        assert nxt == page[-1][0] + 1
        seq = nxt
        if nxt >= int(root.find("s:Header", NS).attrib["lastSequence"]) + 1:
            break
    seqs = [o[0] for o in obs]
    assert seqs == list(range(start, start + len(seqs))), "sequence numbers not contiguous"
    executions = [o[3] for o in obs if o[2] == "execution"]
    assert "ACTIVE" in executions and executions[-1] == "READY", executions
    lines = [int(o[3]) for o in obs if o[2] == "line"]
    assert max(lines) >= 4
    xs = [float(o[3]) for o in obs if o[2] == "x_pos"]
    assert len(set(xs)) > 2, "X did not move"
    assert [o[3] for o in obs if o[2] == "program"] in ([], [controller.program])
    v = current_values(agent, tmp_path)
    assert v["program"][1] == controller.program
    assert float(v["feed_ovr"][1]) == 100


def test_the_agent_survives_the_controller_and_says_unavailable(controller, agent, tmp_path):
    controller.cli("shutdown")
    controller.process.wait(timeout=30)
    wait_for(lambda: current_values(agent, tmp_path)["avail"][1] == "UNAVAILABLE", what="UNAVAILABLE")
    v = current_values(agent, tmp_path)
    assert v["execution"][1] == "UNAVAILABLE"
    assert v["system"][0] == "Unavailable"
    assert get(agent + "/probe")[0] == 200
