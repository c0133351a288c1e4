"""A decision is declared once: the protocol's ``decision`` message
(ros_hrc.link.protocol.Decision). The loop's Decision is derived from it, a step's report keeps
each of its fields (coordinator.DECISION_IN_REPORT) and /hrc/status carries them under the
same names. These tests fail when msg/Status.msg, or the report, and that declaration
disagree; the last one shows that they would."""
import dataclasses
import typing
from pathlib import Path

from ros_hrc.link import protocol
from ros_hrc.loop.effects import DECISION_IN_REPORT, Decision, StepReport

STATUS_MSG = Path(__file__).resolve().parents[3] / "msg" / "Status.msg"
#: The ROS field type that carries each type of a decision's fields.
ROS_TYPES = {str: "string", float: "float64", bool: "bool",
             typing.Tuple[float, ...]: "float64[]", typing.Tuple[str, ...]: "string[]"}


def declared():
    """The fields of a decision as the protocol declares them: its message's own fields but
    the step (every message of a step has one) and the envelope."""
    return [f.name for f in dataclasses.fields(protocol.Decision)
            if f.name not in ("step", "extra", *protocol.ENVELOPE_FIELDS)]


def message_fields(text):
    """name -> ROS type of the fields of a .msg file's text."""
    fields = {}
    for line in text.splitlines():
        words = line.split("#", 1)[0].split()
        if len(words) == 2:
            fields[words[1]] = words[0]
    return fields


def disagreements(status_text):
    """Where a Status.msg text and the declaration of a decision disagree (empty: nowhere)."""
    status = message_fields(status_text)
    kinds = typing.get_type_hints(Decision)
    problems = []
    for name in declared():
        carried_as, wanted = DECISION_IN_REPORT[name], ROS_TYPES[kinds[name]]
        if carried_as not in status:
            problems.append(f"Status.msg has no {carried_as} (a decision's {name})")
        elif status[carried_as] != wanted:
            problems.append(f"Status.msg's {carried_as} is {status[carried_as]}, not {wanted} "
                            f"(a decision's {name})")
    return problems


def test_the_loop_s_decision_has_the_protocol_s_fields_in_its_order():
    assert [f.name for f in dataclasses.fields(Decision)] == declared()
    assert list(DECISION_IN_REPORT) == declared()


def test_a_step_s_report_keeps_every_field_of_a_decision_with_its_type():
    report = typing.get_type_hints(StepReport)
    for name, kind in typing.get_type_hints(Decision).items():
        assert report[DECISION_IN_REPORT[name]] == kind, name


def test_status_msg_carries_every_field_of_a_decision_with_its_type():
    assert disagreements(STATUS_MSG.read_text()) == []


def test_a_decision_message_is_taken_whole():
    message = protocol.Decision(3, "rPoint_obj", [0.25, 0.75], belief_states=["S0", "S2"],
                                decision_ms=2.5, surprise=True, rule="help", epoch=7,
                                reply_to=11)
    assert Decision.of(message) == Decision("rPoint_obj", (0.25, 0.75), ("S0", "S2"), 2.5,
                                            True, "help")
    valued = protocol.Decision(3, "rGrasp_obj", [1.0], action_names=["rIdle", "rGrasp_obj"],
                               action_values=[11.9, 12.3])
    assert Decision.of(valued) == Decision("rGrasp_obj", (1.0,), action_names=(
        "rIdle", "rGrasp_obj"), action_values=(11.9, 12.3))
    # What the message leaves out is empty, never None.
    assert Decision.of(protocol.Decision(0, "rIdle", [1.0])) == Decision(
        "rIdle", belief=(1.0,), belief_states=(), decision_ms=0.0, surprise=False, rule="",
        action_names=(), action_values=())


def test_a_status_msg_that_disagrees_is_caught():
    text = STATUS_MSG.read_text()
    without_rule = "\n".join(line for line in text.splitlines()
                             if not line.startswith("string rule "))
    assert disagreements(without_rule) == ["Status.msg has no rule (a decision's rule)"]
    narrowed = text.replace("float64 decision_ms", "float32 decision_ms")
    assert disagreements(narrowed) == ["Status.msg's decision_ms is float32, not float64 "
                                       "(a decision's decision_ms)"]
