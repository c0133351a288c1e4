"""The protocol of DESIGN §6 without a socket: every message type round-trips, and every kind of
malformed input is rejected with a ProtocolError whose reason says what is wrong."""
import json

import pytest

from ros_hrc.errors import LinkError, ProtocolError
from ros_hrc.link.protocol import (BELIEF_TOLERANCE, ERR_INVALID, MAX_MESSAGE_BYTES,
                                   MESSAGE_TYPES, Ack, Action, Decision, Error, Hello,
                                   MessageError, NextState, Observation, Reaction, Reset, Step,
                                   Configure, TaskEnd, TaskReport, decode, encode, error_message, error_reply, from_dict)

# One message of each type, with every optional field set, and one with none of them.
FULL_MESSAGES = [
    Hello(who="despot_mdp", version=2, id=1),
    Step(step=3, action="idle", state="evaluating", reward=-1.5, state_index=4,
         belief={"evaluating": 0.8, "tired": 0.2}, manual=True, epoch=2, id=17),
    Reaction(step=3, state="RobotInterfered", state_index=8, rule="robot_grasped", reward=-1.0,
             manual=False, epoch=2, id=21),
    Observation(step=3, observation="O35", bits=35, state="S2", elapsed=12.5, epoch=2, id=18),
    Decision(step=3, action="rPoint_obj", belief=[0.1, 0.2, 0.7],
             belief_states=["S0", "S1", "S2"], decision_ms=12.5, surprise=False,
             rule="attempt_failed", epoch=2, reply_to=18),
    Action(step=3, action="rPoint_obj", belief=[0.1, 0.2, 0.7],
           belief_states=["S0", "S1", "S2"], decision_ms=12.5, epoch=2, id=19),
    Reset(reason="enter pressed", episode=4, epoch=3, id=20),
    NextState(state=4, epoch=2, id=2 ** 53 - 1),
    Ack(step=3, of="step", action="rPoint_obj", success=True, result="pointing", episode=4,
        episode_over=True, end_reason="human_has_object", epoch=2, reply_to=17),
    Error(message="bad thing", in_reply_to="step", step=3, code="stale", epoch=0,
          reply_to=0),
    Reset(reason="task 2 over", episode=5, task_index=3, true_type="expert>tired@0.50",
          human_model="expert", drift_to="tired", drift=0.5, epoch=4, id=22),
    TaskEnd(task_index=3, outcome="success", who_succeeded="robot", warnings=1, preemptions=0,
            steps=12, duration=21.4, utility=0.77, epoch=4, id=23),
    TaskReport(selector="bpr", policy="policy3", robot_model="/m/policy3.pomdpx",
               type_names=["a", "b"], type_belief=[0.29, 0.71], signature=[0, 3, 63],
               total_disc_reward=4.5, epoch=4, reply_to=23),
    Configure(reason="/hrc/configure called", id=24),
]
MINIMAL_MESSAGES = [
    Hello(who="hrc_obs"),
    Step(3, "idle", "evaluating"),
    Reaction(3, "Evaluating"),
    Observation(0, "O0", 0, "S0"),
    Decision(0, "rIdle", [1.0]),
    Action(0, "rIdle"),
    Reset(),
    NextState(None),
    Ack(0),
    Error("oops"),
    TaskEnd(1, "timeout", 0, 0, 40, 80.0, -0.5),
    TaskReport("random", "base"),
    Configure(),
]


def test_every_message_type_is_covered_by_the_round_trip_tests():
    assert {m.type for m in FULL_MESSAGES} == set(MESSAGE_TYPES)
    assert {m.type for m in MINIMAL_MESSAGES} == set(MESSAGE_TYPES)


@pytest.mark.parametrize("msg", FULL_MESSAGES + MINIMAL_MESSAGES, ids=lambda m: m.type)
def test_message_round_trips_through_one_text_frame(msg):
    text = encode(msg)
    assert isinstance(text, str) and "\n" not in text
    obj = json.loads(text)
    assert next(iter(obj)) == "type" and obj["type"] == msg.type
    assert decode(text) == msg


def test_design_examples_decode_as_written():
    assert decode('{"type":"step","step":3,"action":"idle","state":"evaluating"}') == \
        Step(3, "idle", "evaluating")
    assert decode('{"type":"observation","step":3,"observation":"O35","bits":35,"state":"S2"}') \
        == Observation(3, "O35", 35, "S2")
    assert decode('{"type":"action","step":3,"action":"rPoint_obj","belief":[0.5,0.5]}') == \
        Action(3, "rPoint_obj", (0.5, 0.5))
    assert decode('{"type":"reset"}') == Reset()
    assert decode('{"type":"next_state","state":4}') == NextState(4)
    assert decode('{"type":"ack","step":3}') == Ack(3)
    assert decode('{"type":"error","message":"..."}') == Error("...")


def test_optional_fields_left_unset_are_not_sent_but_a_null_next_state_is():
    assert json.loads(encode(Step(1, "idle", "tired"))) == \
        {"type": "step", "step": 1, "action": "idle", "state": "tired"}
    assert json.loads(encode(NextState(None))) == {"type": "next_state", "state": None}


def test_a_next_state_without_its_state_key_is_rejected_rather_than_guessed():
    with pytest.raises(ProtocolError, match='missing field "state"'):
        decode('{"type":"next_state"}')


def test_unknown_extra_fields_are_tolerated_and_passed_on():
    msg = decode('{"type":"ack","step":2,"observation":"O3","future":{"x":[1,2]}}')
    assert msg == Ack(2, extra={"observation": "O3", "future": {"x": [1, 2]}})
    assert json.loads(encode(msg))["future"] == {"x": [1, 2]}


def test_numbers_are_normalised_so_equal_messages_compare_equal():
    msg = decode('{"type":"action","step":1,"action":"rIdle","belief":[1,0]}')
    assert msg.belief == (1.0, 0.0) and all(isinstance(p, float) for p in msg.belief)
    assert msg == Action(1, "rIdle", [1.0, 0.0])


def test_a_belief_within_the_tolerance_is_accepted():
    almost = [0.142857] * 7  # a belief printed with 6 digits sums to 0.999999
    assert Action(0, "rIdle", almost).belief == tuple(almost)
    assert abs(sum(almost) - 1) < BELIEF_TOLERANCE


def _frame(**fields):
    return json.dumps(fields)


STEP = {"type": "step", "step": 1, "action": "idle", "state": "tired"}
ACTION = {"type": "action", "step": 1, "action": "rIdle", "belief": [0.5, 0.5]}
OBSERVATION = {"type": "observation", "step": 1, "observation": "O3", "bits": 3, "state": "S1"}

# (case name, frame, words the reason must contain)
MALFORMED = [
    ("binary frame", b'{"type":"reset"}', "binary frame"),
    ("bytearray frame", bytearray(b"\x00\x01"), "binary frame"),
    ("not a frame at all", 42, "must be text"),
    ("invalid JSON", '{"type": "step",', "invalid JSON"),
    ("empty frame", "", "invalid JSON"),
    ("NaN literal", '{"type":"action","step":1,"action":"a","belief":[NaN]}', "NaN"),
    ("Infinity literal", '{"type":"ack","step":Infinity}', "Infinity"),
    ("duplicate field", '{"type":"ack","step":1,"step":2}', 'field "step" appears twice'),
    ("nested too deeply", "[" * 50000, "nested too deeply"),
    ("array, not object", "[1, 2]", "must be a JSON object, got array"),
    ("string, not object", '"reset"', "must be a JSON object, got string"),
    ("null", "null", "must be a JSON object, got null"),
    ("missing type", '{"step": 1}', 'missing field "type"'),
    ("type not a string", '{"type": 7}', 'field "type" must be a string'),
    ("unknown type", '{"type": "dance"}', 'unknown message type "dance"'),
    ("missing step", _frame(**{k: v for k, v in STEP.items() if k != "step"}),
     'step message: missing field "step"'),
    ("missing action", _frame(**{k: v for k, v in STEP.items() if k != "action"}),
     'missing field "action"'),
    ("missing observation bits",
     _frame(**{k: v for k, v in OBSERVATION.items() if k != "bits"}), 'missing field "bits"'),
    ("missing decision belief", _frame(type="decision", step=1, action="rIdle"),
     'decision message: missing field "belief"'),
    ("missing hello who", _frame(type="hello"), 'missing field "who"'),
    ("missing error message", _frame(type="error"), 'missing field "message"'),
    ("step is a string", _frame(**{**STEP, "step": "3"}), '"step" must be an integer'),
    ("step is a float", _frame(**{**STEP, "step": 3.0}), '"step" must be an integer'),
    ("step is a boolean", _frame(**{**STEP, "step": True}), '"step" must be an integer'),
    ("negative step", _frame(**{**STEP, "step": -1}), '"step" must be in 0..4294967295, got -1'),
    ("action not a string", _frame(**{**STEP, "action": 2}), '"action" must be a string'),
    ("empty state", _frame(**{**STEP, "state": ""}), '"state" must not be empty'),
    ("reward not a number", _frame(**{**STEP, "reward": "high"}), '"reward" must be a number'),
    ("reward too large to be finite", '{"type":"step","step":1,"action":"a","state":"s",'
     '"reward":1e999}', '"reward" must be finite'),
    ("manual not a boolean", _frame(**{**STEP, "manual": 1}), '"manual" must be true or false'),
    ("step belief not an object", _frame(**{**STEP, "belief": [1.0]}), "must be an object"),
    ("step belief not summing to 1", _frame(**{**STEP, "belief": {"a": 0.5}}), "must sum to 1"),
    ("negative state_index", _frame(**{**STEP, "state_index": -2}), '"state_index" must be in 0..255'),
    # 127: the seed's six bits and a task's seventh (64, the object left the belt: fabric)
    ("bits above 127", _frame(**{**OBSERVATION, "bits": 128}),
     '"bits" must be in 0..127, got 128'),
    ("negative bits", _frame(**{**OBSERVATION, "bits": -1}), '"bits" must be in 0..127'),
    ("belief not an array", _frame(**{**ACTION, "belief": 1.0}), "array of probabilities"),
    ("empty belief", _frame(**{**ACTION, "belief": []}), '"belief" must not be empty'),
    ("belief entry not a number", _frame(**{**ACTION, "belief": ["x", 1]}),
     '"belief[0]" must be a number'),
    ("non-finite belief", '{"type":"action","step":1,"action":"a","belief":[1e999,0]}',
     '"belief[0]" must be finite'),
    ("negative belief", _frame(**{**ACTION, "belief": [-0.5, 1.5]}),
     '"belief[0]" must not be negative'),
    ("belief summing to more than 1", _frame(**{**ACTION, "belief": [0.5, 0.6]}),
     "must sum to 1"),
    ("belief summing to less than 1", _frame(**{**ACTION, "belief": [0.2, 0.2]}),
     "sums to 0.4"),
    ("belief_states of another length", _frame(**{**ACTION, "belief_states": ["S0"]}),
     "has 1 names for 2 probabilities"),
    ("belief_states repeated", _frame(**{**ACTION, "belief_states": ["S0", "S0"]}),
     "must not repeat"),
    ("negative decision time", _frame(**{**ACTION, "decision_ms": -1}), '"decision_ms" must be'),
    ("next_state negative", _frame(type="next_state", state=-1), '"state" must be in 0..255'),
    ("next_state a name", _frame(type="next_state", state="tired"), "must be an integer"),
    ("ack success not a boolean", _frame(type="ack", step=1, success="yes"), "true or false"),
    ("hello version 0", _frame(type="hello", who="x", version=0), '"version" must be in 1..2147483647'),
    ("oversized", _frame(type="reset", padding="x" * MAX_MESSAGE_BYTES), "message too large"),
    ("oversized in UTF-8 bytes only",  # two bytes per character
     '{"type":"reset","padding":"' + "\u00e9" * (MAX_MESSAGE_BYTES // 2 + 8) + '"}',
     "message too large"),
]


@pytest.mark.parametrize("frame,words", [(f, w) for _, f, w in MALFORMED],
                         ids=[name for name, _, _ in MALFORMED])
def test_malformed_input_raises_a_protocol_error_with_a_precise_reason(frame, words):
    with pytest.raises(ProtocolError) as caught:
        decode(frame)
    assert isinstance(caught.value, LinkError)
    assert words in str(caught.value)
    assert caught.value.reason == str(caught.value)


def test_the_utf8_oversize_case_is_short_in_characters_but_long_in_bytes():
    frame = MALFORMED[-1][1]
    assert len(frame) <= MAX_MESSAGE_BYTES < len(frame.encode("utf-8"))


def test_a_rejection_knows_the_type_and_step_of_the_message_when_they_could_be_read():
    with pytest.raises(MessageError) as caught:
        decode(_frame(**{**ACTION, "step": 9, "belief": [2.0]}))
    assert caught.value.msg_type == "action" and caught.value.step == 9
    with pytest.raises(MessageError) as caught:
        decode("[]")
    assert caught.value.msg_type is None and caught.value.step is None


def test_an_invalid_message_cannot_be_built_either():
    with pytest.raises(ProtocolError, match="must be in 0..4294967295"):
        Step(-1, "idle", "tired")
    with pytest.raises(ProtocolError, match="must be finite"):
        Action(0, "rIdle", [float("nan"), 1.0])
    with pytest.raises(ProtocolError, match="named field"):
        Ack(1, extra={"step": 2})


def test_a_rejected_value_is_quoted_only_briefly():
    with pytest.raises(ProtocolError) as caught:
        decode(_frame(**{**STEP, "action": ["x" * 5000]}))
    assert len(str(caught.value)) < 200


def test_encode_refuses_what_the_other_side_would_reject():
    with pytest.raises(ProtocolError, match="too large"):
        encode(Reset(extra={"padding": "x" * MAX_MESSAGE_BYTES}))
    with pytest.raises(ProtocolError, match="cannot be encoded"):
        encode(Ack(1, extra={"when": object()}))
    with pytest.raises(ProtocolError, match="only protocol messages"):
        encode({"type": "reset"})


def test_from_dict_validates_an_already_parsed_object():
    assert from_dict({"type": "ack", "step": 4}) == Ack(4)
    with pytest.raises(ProtocolError, match="must be an integer"):
        from_dict({"type": "ack", "step": None})


def test_error_reply_answers_a_rejected_message_with_its_type_step_and_reason():
    with pytest.raises(MessageError) as caught:
        decode(_frame(**{**OBSERVATION, "step": 5, "bits": 199}))
    reply = decode(error_reply(caught.value))
    assert reply == Error(message=caught.value.reason, in_reply_to="observation", step=5,
                          code=ERR_INVALID)


def test_error_reply_names_the_class_of_any_other_exception():
    reply = decode(error_reply(KeyError("rGrasp"), in_reply_to="action"))
    assert reply.message == "KeyError: 'rGrasp'" and reply.in_reply_to == "action"
    assert decode(error_reply(RuntimeError())).message == "RuntimeError: "


def test_error_reply_stays_small_and_well_formed_whatever_it_is_given():
    reply = decode(error_reply(ValueError("x" * 100000), in_reply_to="t" * 1000, step=-3))
    assert len(reply.message) < 2000 and len(reply.in_reply_to) < 100 and reply.step is None
    with pytest.raises(MessageError) as caught:
        decode(_frame(type="z" * 10000))
    assert len(error_reply(caught.value)) < 2000
    assert error_message(ProtocolError("plain")).message == "plain"


# -- observation.elapsed (issue #22: a robot whose rules count simulated time) ------------------

def test_an_observation_may_say_how_long_the_episode_has_run():
    """``elapsed``: simulated seconds since the episode's reset, optional (absent: unknown)."""
    assert decode('{"type":"observation","step":3,"observation":"O35","bits":35,"state":"S2",'
                  '"elapsed":15}').elapsed == 15.0
    assert Observation(3, "O35", 35, "S2", elapsed=0).elapsed == 0.0
    plain = decode('{"type":"observation","step":3,"observation":"O35","bits":35,"state":"S2"}')
    assert plain.elapsed is None and "elapsed" not in json.loads(encode(plain))


@pytest.mark.parametrize("value, reason", [
    ("-0.5", "must be >= 0.0"), ("1e999", "must be finite"), ('"15"', "must be a number"),
    ("true", "must be a number"), ("[15]", "must be a number"),
])
def test_an_observation_with_a_bad_elapsed_is_refused(value, reason):
    with pytest.raises(ProtocolError, match=f'"elapsed" {reason}'):
        decode('{"type":"observation","step":3,"observation":"O35","bits":35,"state":"S2",'
               f'"elapsed":{value}}}')
    if value in ("-0.5", "true"):
        with pytest.raises(MessageError):
            Observation(3, "O35", 35, "S2", elapsed=json.loads(value))
    with pytest.raises(MessageError, match="must be finite"):
        Observation(3, "O35", 35, "S2", elapsed=float("nan"))
