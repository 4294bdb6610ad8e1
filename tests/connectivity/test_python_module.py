"""The Python module `cnc` drives the simulated mill end to end, as a
LinuxCNC script would drive `linuxcnc` (docs/connectivity.md)."""

import pytest

import cnc
from conftest import wait_for


def poll(instance):
    s = cnc.stat(instance)
    s.poll()
    return s


def test_constants_have_linuxcnc_values():
    assert (cnc.STATE_ESTOP, cnc.STATE_ESTOP_RESET, cnc.STATE_OFF, cnc.STATE_ON) == (1, 2, 3, 4)
    assert (cnc.MODE_MANUAL, cnc.MODE_AUTO, cnc.MODE_MDI) == (1, 2, 3)
    assert (cnc.INTERP_IDLE, cnc.INTERP_READING, cnc.INTERP_PAUSED, cnc.INTERP_WAITING) == (1, 2, 3, 4)
    assert (cnc.RCS_DONE, cnc.RCS_EXEC, cnc.RCS_ERROR) == (1, 2, 3)
    assert (cnc.AUTO_RUN, cnc.AUTO_PAUSE, cnc.AUTO_RESUME, cnc.AUTO_STEP) == (0, 1, 2, 3)


def test_no_controller_raises_cnc_error():
    with pytest.raises(cnc.error, match="not running"):
        cnc.stat("no-such-instance-here")


def test_stat_after_start_shows_estop_and_the_configuration(controller):
    s = poll(controller.instance)
    assert s.task_state == cnc.STATE_ESTOP
    assert s.estop == 1
    assert s.joints == 3
    assert len(s.position) == 9 and len(s.actual_position) == 9
    assert s.ini_filename.endswith("sim.ini")
    assert s.axis_mask & 7 == 7
    assert set(s.joint[0]) >= {"homed", "homing", "enabled", "input", "output", "velocity", "ferror_current"}
    assert set(s.spindle[0]) >= {"speed", "direction", "enabled", "brake", "override"}
    assert set(s.axis[0]) >= {"velocity", "min_position_limit", "max_position_limit"}
    # The tool table of the configuration (tool.tbl): index 0 is the spindle.
    ids = [t["id"] for t in s.tool_table]
    assert ids[1:] == [1, 2, 3, 4]
    assert s.tool_table[2]["zoffset"] == pytest.approx(42.5)
    assert s.tool_table[2]["diameter"] == pytest.approx(10.0)


def test_stat_needs_poll_first(controller):
    s = cnc.stat(controller.instance)
    with pytest.raises(cnc.error, match="poll"):
        s.task_state


def test_mdi_in_estop_is_rejected_with_the_controllers_reason(controller):
    c = cnc.command(controller.instance)
    with pytest.raises(cnc.error, match="rejected: .+"):
        c.mode(cnc.MODE_MDI)
        c.mdi("G0 X1")


def test_estop_reset_on_and_home_all(controller):
    c = cnc.command(controller.instance)
    c.state(cnc.STATE_ESTOP_RESET)
    assert c.wait_complete() == cnc.RCS_DONE
    c.state(cnc.STATE_ON)
    assert c.wait_complete() == cnc.RCS_DONE
    s = poll(controller.instance)
    assert s.task_state == cnc.STATE_ON and s.estop == 0 and s.enabled
    c.mode(cnc.MODE_MANUAL)
    c.home(-1)
    assert c.wait_complete(60) == cnc.RCS_DONE
    s = poll(controller.instance)
    assert s.homed[:3] == (1, 1, 1)
    assert all(j["homed"] for j in s.joint[:3])


def test_mdi_moves_the_machine(controller):
    c = cnc.command(controller.instance)
    c.mode(cnc.MODE_MDI)
    c.wait_complete()
    c.mdi("G53 G0 X12 Y7 Z-3")
    assert c.wait_complete(30) == cnc.RCS_DONE
    s = cnc.stat(controller.instance)
    wait_for(lambda: (s.poll(), s.interp_state == cnc.INTERP_IDLE and s.inpos)[1], what="MDI move to end")
    assert s.position[:3] == pytest.approx((12, 7, -3), abs=1e-6)
    assert s.actual_position[:3] == pytest.approx((12, 7, -3), abs=1e-2)
    assert s.task_mode == cnc.MODE_MDI


def test_bad_gcode_raises_the_interpreters_reason_and_posts_an_error(controller):
    e = cnc.error_channel(controller.instance)
    c = cnc.command(controller.instance)
    c.mode(cnc.MODE_MDI)
    with pytest.raises(cnc.error, match="Two g codes used from same modal group"):
        c.mdi("G0 X1 G2")
    found = []
    def error_seen():
        m = e.poll()
        if m and m[0] == cnc.NML_ERROR:
            found.append(m[1])
        return found
    wait_for(error_seen, what="the interpreter's error on the error channel")
    assert "Two g codes" in found[0]


def test_overrides_and_spindle(controller):
    c = cnc.command(controller.instance)
    c.feedrate(0.5)
    c.wait_complete()
    c.spindleoverride(1.2)
    c.wait_complete()
    c.mode(cnc.MODE_MANUAL)
    c.spindle(cnc.SPINDLE_FORWARD, 1000)
    c.wait_complete()
    s = poll(controller.instance)
    assert s.feedrate == pytest.approx(0.5)
    assert s.spindle[0]["override"] == pytest.approx(1.2)
    assert s.spindle[0]["enabled"] == 1 and s.spindle[0]["direction"] == 1
    assert s.spindle[0]["speed"] == pytest.approx(1000)
    c.spindle(cnc.SPINDLE_OFF)
    c.wait_complete()
    c.feedrate(1.0)
    c.spindleoverride(1.0)
    c.wait_complete()
    s = poll(controller.instance)
    assert s.spindle[0]["enabled"] == 0


def test_jog_increment_moves_one_axis(controller):
    c = cnc.command(controller.instance)
    c.mode(cnc.MODE_MANUAL)
    c.teleop_enable(True)
    s = poll(controller.instance)
    x0 = s.position[0]
    c.jog(cnc.JOG_INCREMENT, False, 0, 10, 2.5)
    c.wait_complete(30)
    wait_for(lambda: (s.poll(), abs(s.position[0] - (x0 + 2.5)) < 1e-6 and s.inpos)[1], what="jog to end")


def test_program_runs_to_its_end(controller):
    c = cnc.command(controller.instance)
    c.mode(cnc.MODE_AUTO)
    c.program_open(controller.program)
    c.wait_complete()
    s = poll(controller.instance)
    assert s.file == controller.program
    c.auto(cnc.AUTO_RUN, 0)
    lines = set()
    def done():
        s.poll()
        lines.add(s.current_line)
        return s.interp_state == cnc.INTERP_IDLE and s.inpos
    wait_for(lambda: (s.poll(), s.interp_state != cnc.INTERP_IDLE)[1], what="program start")
    wait_for(done, timeout=120, what="program end")
    # G54 offset of the configuration plus the program's last XY.
    g5x = s.g5x_offset
    assert s.position[0] == pytest.approx(g5x[0] + 30, abs=1e-6)
    assert s.position[1] == pytest.approx(g5x[1] + 20, abs=1e-6)
    assert max(lines) >= 4


def test_pause_and_resume(controller):
    c = cnc.command(controller.instance)
    c.auto(cnc.AUTO_RUN, 0)
    s = cnc.stat(controller.instance)
    wait_for(lambda: (s.poll(), s.interp_state != cnc.INTERP_IDLE)[1], what="program start")
    c.auto(cnc.AUTO_PAUSE)
    wait_for(lambda: (s.poll(), s.task_paused == 1 or s.paused)[1], what="pause")
    c.auto(cnc.AUTO_RESUME)
    wait_for(lambda: (s.poll(), s.interp_state == cnc.INTERP_IDLE)[1], timeout=120, what="program end")


def test_open_of_a_missing_program_raises_with_the_reason(controller):
    c = cnc.command(controller.instance)
    with pytest.raises(cnc.error, match="rejected"):
        c.program_open(controller.work + "/no-such-program.ngc")


def test_error_channel_reads_operator_and_controller_messages(controller):
    e = cnc.error_channel(controller.instance)
    c = cnc.command(controller.instance)
    c.error_msg("tool breakage check failed")
    c.wait_complete()
    c.text_msg("hello from python")
    c.wait_complete()
    msgs = []
    def two():
        m = e.poll()
        if m:
            msgs.append(m)
        return len(msgs) >= 2
    wait_for(two, what="two messages")
    assert (cnc.OPERATOR_ERROR, "tool breakage check failed") in msgs
    assert (cnc.OPERATOR_TEXT, "hello from python") in msgs


def test_bad_arguments_raise_value_error(controller):
    c = cnc.command(controller.instance)
    with pytest.raises(ValueError):
        c.mode(7)
    with pytest.raises(ValueError):
        c.mdi("G0 X1" * 400)


def test_estop_through_the_module(controller):
    c = cnc.command(controller.instance)
    c.state(cnc.STATE_ESTOP)
    s = cnc.stat(controller.instance)
    wait_for(lambda: (s.poll(), s.task_state == cnc.STATE_ESTOP)[1], what="E-stop")
    assert s.estop == 1
