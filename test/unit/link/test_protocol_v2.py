"""Protocol version 2 without a socket: the envelope (epoch, id, reply_to) on every type, the
decision message and the new typed fields, reply matching by correlation id, the dispatch
table, and decode() turning any text at all into a MessageError (never another exception)."""
import json
import random

import pytest

from ros_hrc.link import protocol
from ros_hrc.link.protocol import (ERR_BUSY, ERR_FAILED, ERR_INVALID, ERR_REFUSED,
                                   ERR_SEAT_TAKEN, ERR_STALE, ERR_UNKNOWN_TYPE, ERR_VERSION,
                                   ERROR_CODES, MAX_ENVELOPE_INT, MAX_UINT32, MESSAGE_TYPES,
                                   PROTOCOL_VERSION, Ack, Action, Decision, DispatchTable, Error,
                                   Hello, MessageError, NextState, Observation, Reset, Step,
                                   as_reply, decode, encode, error_message, error_reply,
                                   is_reply_to, reply_error)

# The required fields of each type, as JSON, to which the envelope is added.
BASE = {
    "hello": {"who": "x"},
    "step": {"step": 1, "action": "idle", "state": "tired"},
    "reaction": {"step": 1, "state": "RobotInterfered"},
    "observation": {"step": 1, "observation": "O3", "bits": 3, "state": "S1"},
    "decision": {"step": 1, "action": "rIdle", "belief": [1.0]},
    "action": {"step": 1, "action": "rIdle"},
    "reset": {},
    "next_state": {"state": None},
    "ack": {"step": 1},
    "error": {"message": "no"},
    "task_end": {"task_index": 1, "outcome": "fail", "warnings": 0, "preemptions": 0,
                 "steps": 3, "duration": 69.0, "utility": -0.43},
    "task_report": {"selector": "bpr", "policy": "base"},
    "configure": {},
}


def test_the_envelope_cases_cover_every_type_and_the_version_is_2():
    assert set(BASE) == set(MESSAGE_TYPES)
    assert PROTOCOL_VERSION == 2 and Hello("x").version == 2


@pytest.mark.parametrize("msg_type", sorted(BASE))
@pytest.mark.parametrize("name", ["epoch", "id", "reply_to"])
def test_every_type_carries_the_envelope_and_round_trips_it(msg_type, name):
    for value in (0, 7, MAX_UINT32 if name == "epoch" else MAX_ENVELOPE_INT):
        msg = decode(json.dumps({"type": msg_type, **BASE[msg_type], name: value}))
        assert getattr(msg, name) == value and msg.extra == {}
        assert decode(encode(msg)) == msg
        assert json.loads(encode(msg))[name] == value
    # Unset: not sent at all (null is not a substitute).
    plain = decode(json.dumps({"type": msg_type, **BASE[msg_type]}))
    assert getattr(plain, name) is None and name not in json.loads(encode(plain))


BAD_ENVELOPE = [
    (-1, "must be in 0..9007199254740991, got -1"),
    (MAX_ENVELOPE_INT + 1, "must be in 0..9007199254740991, got 9007199254740992"),
    (10 ** 30, "must be in 0..9007199254740991"),
    (True, "must be an integer, got boolean true"),
    (3.0, "must be an integer, got number 3.0"),
    ("3", 'must be an integer, got string "3"'),
    ([1], "must be an integer, got array"),
]


@pytest.mark.parametrize("msg_type", sorted(BASE))
@pytest.mark.parametrize("name", ["epoch", "id", "reply_to"])
@pytest.mark.parametrize("value,words", BAD_ENVELOPE, ids=[repr(v) for v, _ in BAD_ENVELOPE])
def test_a_bad_envelope_field_is_rejected_with_a_precise_reason(msg_type, name, value, words):
    if name == "epoch":  # the epoch reaches uint32 fields of ROS messages
        words = words.replace(str(MAX_ENVELOPE_INT), str(MAX_UINT32))
        if value == MAX_ENVELOPE_INT + 1:
            words = words.replace(str(MAX_ENVELOPE_INT + 1), str(value))
    with pytest.raises(MessageError) as caught:
        decode(json.dumps({"type": msg_type, **BASE[msg_type], name: value}))
    assert caught.value.reason.startswith(f'{msg_type} message: field "{name}" {words}')
    assert caught.value.msg_type == msg_type and caught.value.code == ERR_INVALID


def test_an_invalid_envelope_cannot_be_built_and_the_envelope_is_keyword_only():
    with pytest.raises(MessageError, match='step message: field "epoch" must be in'):
        Step(1, "idle", "tired", epoch=-1)
    with pytest.raises(MessageError, match='"id" must be an integer'):
        Ack(1, id=False)
    with pytest.raises(TypeError):
        Ack(1, None, None, None, None, None, None, None, 5)  # no ninth positional field


def test_decision_round_trips_and_is_validated_like_an_action_belief():
    msg = Decision(4, "rGrasp_obj", [0.25, 0.75], belief_states=["S0", "S1"], decision_ms=3,
                   surprise=True, rule="warning", reply_to=9, epoch=2)
    obj = json.loads(encode(msg))
    assert obj == {"type": "decision", "step": 4, "action": "rGrasp_obj", "belief": [0.25, 0.75],
                   "belief_states": ["S0", "S1"], "decision_ms": 3.0, "surprise": True,
                   "rule": "warning", "epoch": 2, "reply_to": 9}
    assert decode(encode(msg)) == msg
    bad = [
        ({"belief": [0.5, 0.6]}, "must sum to 1"),
        ({"belief": []}, '"belief" must not be empty'),
        ({"belief": [1.0], "belief_states": ["S0", "S1"]}, "has 2 names for 1 probabilities"),
        ({"surprise": "yes"}, '"surprise" must be true or false'),
        ({"rule": ""}, '"rule" must not be empty'),
        ({"decision_ms": -0.5}, '"decision_ms" must be >= 0'),
    ]
    for change, words in bad:
        with pytest.raises(MessageError, match=words):
            decode(json.dumps({"type": "decision", **BASE["decision"], **change}))


def test_action_needs_no_belief_now_but_names_still_need_one():
    assert decode('{"type":"action","step":2,"action":"rIdle"}') == Action(2, "rIdle")
    assert json.loads(encode(Action(2, "rIdle"))) == {"type": "action", "step": 2,
                                                      "action": "rIdle"}
    with pytest.raises(MessageError, match='"belief_states" is given without a belief'):
        Action(2, "rIdle", belief_states=["S0"])


def test_the_new_ack_reset_and_error_fields():
    ack = Ack(5, of="step", episode=2, episode_over=True, end_reason="object_lost")
    assert decode(encode(ack)) == ack
    assert Ack(5, result="").result == ""  # a result may be empty
    for change, words in [({"episode": -1}, '"episode" must be in 0..4294967295'),
                          ({"episode_over": 1}, '"episode_over" must be true or false'),
                          ({"end_reason": ""}, '"end_reason" must not be empty')]:
        with pytest.raises(MessageError, match=words):
            decode(json.dumps({"type": "ack", "step": 1, **change}))
    assert decode('{"type":"reset","episode":3}') == Reset(episode=3)
    with pytest.raises(MessageError, match='"episode" must be an integer'):
        decode('{"type":"reset","episode":"3"}')
    err = Error("too late", code=ERR_STALE)
    assert json.loads(encode(err)) == {"type": "error", "message": "too late", "code": "stale"}
    assert decode('{"type":"error","message":"x","code":"from_the_future"}').code == \
        "from_the_future"  # fields may grow: an unknown code is still taken
    with pytest.raises(MessageError, match='"code" must be a string'):
        decode('{"type":"error","message":"x","code":4}')


def test_error_codes_are_module_constants():
    assert {ERR_STALE, ERR_BUSY, ERR_SEAT_TAKEN, ERR_INVALID, ERR_UNKNOWN_TYPE, ERR_REFUSED,
            ERR_FAILED, ERR_VERSION, "episode_over", "not_ready",
            "unauthorized"} == set(ERROR_CODES)
    assert (ERR_STALE, ERR_BUSY, ERR_SEAT_TAKEN, ERR_INVALID, ERR_UNKNOWN_TYPE, ERR_REFUSED,
            ERR_FAILED) == ("stale", "busy", "seat_taken", "invalid", "unknown_type", "refused",
                            "failed")


# -- replies ---------------------------------------------------------------------------------

def test_is_reply_to_matches_by_correlation_id_when_the_request_has_one():
    obs = Observation(3, "O35", 35, "S2", id=11, epoch=1)
    assert is_reply_to(Decision(3, "rIdle", [1.0], reply_to=11), obs)
    assert is_reply_to(Ack(99, of="something else", reply_to=11), obs)  # the id decides
    assert is_reply_to(Error("no", in_reply_to="step", step=0, reply_to=11), obs)
    assert not is_reply_to(Decision(3, "rIdle", [1.0], reply_to=12), obs)
    assert not is_reply_to(Decision(3, "rIdle", [1.0]), obs)  # the step alone is not enough
    assert not is_reply_to(Action(3, "rIdle", reply_to=11), obs)  # not a reply type
    assert not is_reply_to(Step(3, "idle", "tired", reply_to=11), obs)


def test_is_reply_to_keeps_the_step_and_type_rules_without_an_id():
    step = Step(3, "idle", "tired")
    assert is_reply_to(Ack(3), step) and is_reply_to(Ack(3, of="step"), step)
    assert not is_reply_to(Ack(4), step) and not is_reply_to(Ack(3, of="action"), step)
    assert is_reply_to(Error("no", step=3), step)
    assert is_reply_to(Error("no", in_reply_to="step"), step)
    assert not is_reply_to(Error("no", in_reply_to="action", step=3), step)
    assert is_reply_to(Ack(0, of="reset"), Reset()) and not is_reply_to(Ack(0), Reset())
    assert not is_reply_to(Action(3, "rIdle", belief=[1.0]), step)
    obs = Observation(3, "O35", 35, "S2")
    assert is_reply_to(Decision(3, "rIdle", [1.0]), obs)
    assert not is_reply_to(Decision(4, "rIdle", [1.0]), obs)
    assert not is_reply_to(Decision(3, "rIdle", [1.0]), step)
    # A reply that names a request id answers that request, not this one.
    assert not is_reply_to(Ack(3, reply_to=5), step)


def test_as_reply_and_reply_error_answer_a_request():
    request = Action(6, "rGrasp_obj", id=41, epoch=3)
    assert as_reply(Ack(6), request) == Ack(6, reply_to=41, epoch=3)
    assert as_reply(Ack(6, epoch=4), request) == Ack(6, reply_to=41, epoch=4)  # kept
    plain = Ack(6)
    assert as_reply(plain, Action(6, "rIdle")) is plain
    err = reply_error(request, "the robot is busy", ERR_BUSY)
    assert err == Error("the robot is busy", code="busy", in_reply_to="action", step=6,
                        reply_to=41, epoch=3)
    assert is_reply_to(err, request)
    assert reply_error(Reset(), "x" * 5000, ERR_REFUSED).message.endswith("...")


def test_error_message_carries_the_rejected_frames_id_and_epoch():
    with pytest.raises(MessageError) as caught:
        decode('{"type":"observation","step":5,"bits":199,"observation":"O3","state":"S1",'
               '"id":77,"epoch":4}')
    assert caught.value.msg_id == 77 and caught.value.epoch == 4
    reply = decode(error_reply(caught.value))
    assert reply == Error(caught.value.reason, in_reply_to="observation", step=5, code="invalid",
                          reply_to=77, epoch=4)
    # Unreadable ids are left out, not echoed.
    with pytest.raises(MessageError) as caught:
        decode('{"type":"ack","step":1,"id":-4}')
    assert caught.value.msg_id is None and decode(error_reply(caught.value)).reply_to is None
    with pytest.raises(MessageError) as caught:
        decode('{"type":"teleport","id":3}')
    assert caught.value.code == ERR_UNKNOWN_TYPE and error_message(caught.value).reply_to == 3
    assert error_message(RuntimeError("boom"), reply_to=8, epoch=1) == \
        Error("RuntimeError: boom", code=ERR_FAILED, reply_to=8, epoch=1)
    assert error_message(ValueError(), reply_to=-1, epoch=2 ** 60).reply_to is None


# -- the dispatch table ----------------------------------------------------------------------

def make_table():
    table = DispatchTable("hrc_robot")
    seen = []

    @table.on(Action)
    def carry_out(msg, peer):
        seen.append((msg, peer))
        return Ack(msg.step, of=msg.type, action=msg.action, success=True)

    table.on(Reset, lambda msg, peer: Ack(0, of="reset"))
    return table, seen


def test_dispatch_table_routes_by_type_and_stamps_the_reply():
    table, seen = make_table()
    order = Action(2, "rPoint_obj", id=5, epoch=1)
    assert table(order, "peer-1") == Ack(2, of="action", action="rPoint_obj", success=True,
                                          reply_to=5, epoch=1)
    assert seen == [(order, "peer-1")]
    assert table(Reset(reason="r")) == Ack(0, of="reset")
    assert table.types == ("action", "reset") and table.handles(Action)
    assert not table.handles(Step)


def test_dispatch_table_refuses_an_unknown_type_with_unknown_type():
    table, seen = make_table()
    reply = table(Step(4, "idle", "tired", id=9, epoch=2), None)
    assert reply == Error("hrc_robot does not take step messages", code=ERR_UNKNOWN_TYPE,
                          in_reply_to="step", step=4, reply_to=9, epoch=2)
    assert table(NextState(None)).code == ERR_UNKNOWN_TYPE and seen == []


def test_dispatch_table_never_answers_an_error():
    table, _ = make_table()
    assert table(Error("you are wrong", reply_to=3)) is None
    got = []

    def answer_back(msg, peer):
        got.append(msg)
        return Error("no, you are")

    table.on(Error, answer_back)
    assert table(Error("you are wrong")) is None and len(got) == 1


def test_dispatch_table_registration_is_checked():
    table, _ = make_table()
    with pytest.raises(ValueError, match="already registered"):
        table.on(Action, lambda m, p: None)
    with pytest.raises(TypeError):
        table.on(dict, lambda m, p: None)
    with pytest.raises(TypeError):
        table.on(Step, "not callable")
    boom = DispatchTable("t")
    boom.on(Step, lambda m, p: 1 / 0)
    with pytest.raises(ZeroDivisionError):  # the server turns it into an error reply
        boom(Step(1, "idle", "tired"))


# -- decode never raises anything but MessageError ------------------------------------------

NASTY = [
    '{"type":"ack","step":1' + "0" * 5000 + "}",           # 5000-digit integer
    '{"type":"ack","step":' + "9" * 5000 + "}",
    '{"type":"ack","step":1,"x":' + "-" + "1" * 4400 + "}",
    "\ud800",                                              # lone surrogate in the text
    '{"type":"ack","step":1,"r":"\ud800"}',
    '{"type":"ack","step":1,"r":"\\ud800"}',                # ... as a JSON escape
    '{"type":"\\udfff"}',
    '{"type":"ack","step":1,"\\ud83d":1}',                 # in a key
    '{"type":"step","step":1,"action":"a","state":"s","reward":' + "1" * 400 + "}",
    '{"type":"ack","step":1e400}',
    '{"type":"ack","step":-0}',
    "\x00", "{" * 100000, '{"a":' * 3000, "\ufeff{}", '{"type":"ack","step":1}\x00',
]


@pytest.mark.parametrize("frame", NASTY, ids=range(len(NASTY)))
def test_decode_turns_any_text_into_a_message_error_and_an_error_reply(frame):
    try:
        msg = decode(frame)
    except MessageError as exc:
        reply = decode(error_reply(exc))  # the reply itself is always sendable
        assert isinstance(reply, Error) and reply.code == ERR_INVALID
        encode(reply).encode("utf-8")
    else:
        assert isinstance(msg, protocol.Message)


def test_a_5000_digit_integer_and_a_lone_surrogate_are_rejected_precisely():
    with pytest.raises(MessageError, match="too many digits"):
        decode(NASTY[0])
    with pytest.raises(MessageError, match="lone surrogate"):
        decode(NASTY[3])
    with pytest.raises(MessageError, match="lone surrogate"):
        decode(NASTY[5])
    # A surrogate pair is a real character and passes.
    assert decode('{"type":"ack","step":1,"result":"\\ud83d\\ude00"}').result == "\U0001F600"


def test_decode_of_random_text_never_raises_anything_else():
    rng = random.Random(7)
    alphabet = '{}[]",:0123456789.eE+-truefalsnl \\u\ud800\udfff\x00abc\u00e9'
    pieces = ['{"type":"ack","step":', '{"type":"decision","belief":[', '"id":', '"epoch":']
    for _ in range(3000):
        text = rng.choice(pieces) + "".join(rng.choice(alphabet)
                                            for _ in range(rng.randrange(40)))
        try:
            decode(text)
        except MessageError as exc:
            encode(error_message(exc))
