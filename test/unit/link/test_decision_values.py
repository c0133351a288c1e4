"""A decision carries the planner's value of each action it compared (``action_names``,
``action_values``) and, from a robot model of human types, its belief over the types
(``type_names``, ``type_belief``): they go over the wire and come back whole, a decision of an
older peer without them still parses (and reaches the loop as empty lists), and wrong ones are
refused in one line that names the field."""
import json

import pytest

from ros_hrc.link.protocol import Decision, MessageError, decode, encode
from ros_hrc.loop.effects import Decision as LoopDecision

BELIEF = [0.97, 0.0, 0.03, 0.0, 0.0, 0.0, 0.0]


def test_the_values_go_over_the_wire_and_come_back_whole():
    sent = Decision(4, "rGrasp_obj", BELIEF, action_names=["rIdle", "rGrasp_obj"],
                    action_values=[11.9, 12.345678901234567], epoch=2, reply_to=9)
    wire = json.loads(encode(sent))
    assert wire["action_names"] == ["rIdle", "rGrasp_obj"]
    assert wire["action_values"] == [11.9, 12.345678901234567]
    received = decode(encode(sent))
    assert received == sent
    assert LoopDecision.of(received).action_values == (11.9, 12.345678901234567)
    assert LoopDecision.of(received).action_names == ("rIdle", "rGrasp_obj")


def test_the_type_belief_goes_over_the_wire_and_comes_back_whole():
    sent = Decision(4, "rIdle", BELIEF, type_names=["tired", "expert"],
                    type_belief=[0.62, 0.38], epoch=2, reply_to=9)
    wire = json.loads(encode(sent))
    assert (wire["type_names"], wire["type_belief"]) == (["tired", "expert"], [0.62, 0.38])
    received = decode(encode(sent))
    assert received == sent
    taken = LoopDecision.of(received)
    assert (taken.type_names, taken.type_belief) == (("tired", "expert"), (0.62, 0.38))
    assert LoopDecision.of(Decision(4, "rIdle", BELIEF)).type_belief == ()


def test_a_decision_of_an_older_peer_without_values_parses():
    old = ('{"type":"decision","step":3,"action":"rPoint_obj","belief":[0.05,0.0,0.7,0.25,0.0,'
           '0.0,0.0],"decision_ms":41.7,"epoch":7,"reply_to":12}')
    message = decode(old)
    assert message.action_names is None and message.action_values is None
    assert "action_values" not in json.loads(encode(message))
    taken = LoopDecision.of(message)
    assert taken.action == "rPoint_obj"
    assert (taken.action_names, taken.action_values) == ((), ())


@pytest.mark.parametrize("fields, reason", [
    ({"action_names": ["rIdle"]}, 'field "action_names" is given without action_values'),
    ({"action_values": [1.0]}, 'field "action_values" is given without action_names'),
    ({"action_names": ["rIdle", "rGrasp_obj"], "action_values": [1.0]},
     'field "action_values" has 1 numbers for 2 action_names'),
    ({"action_names": ["rIdle", "rIdle"], "action_values": [1.0, 2.0]},
     'field "action_names" must not repeat a name'),
    ({"action_names": ["rIdle"], "action_values": ["high"]},
     'field "action_values[0]" must be a number, got string "high"'),
    ({"action_names": ["rIdle"], "action_values": 1.0},
     'field "action_values" must be an array of numbers, got number 1.0'),
    ({"action_names": [""], "action_values": [1.0]}, 'field "action_names[0]" must not be empty'),
    ({"type_names": ["tired"]}, 'field "type_names" is given without type_belief'),
    ({"type_belief": [1.0]}, 'field "type_belief" is given without type_names'),
    ({"type_names": ["tired", "expert"], "type_belief": [1.0]},
     'field "type_names" has 2 names for 1 probabilities'),
    ({"type_names": ["tired", "expert"], "type_belief": [0.7, 0.7]},
     'field "type_belief" must sum to 1 (within 0.0001), sums to 1.4'),
    ({"type_names": ["tired", "tired"], "type_belief": [0.5, 0.5]},
     'field "type_names" must not repeat a name'),
])
def test_wrong_values_are_refused_in_one_line(fields, reason):
    frame = json.dumps({"type": "decision", "step": 1, "action": "rIdle", "belief": [1.0],
                        **fields})
    with pytest.raises(MessageError) as refused:
        decode(frame)
    text = str(refused.value)
    assert text == f"decision message: {reason}" and "\n" not in text


def test_an_infinite_value_is_refused():
    frame = ('{"type":"decision","step":1,"action":"rIdle","belief":[1.0],'
             '"action_names":["rIdle"],"action_values":[1e999]}')
    with pytest.raises(MessageError, match=r'"action_values\[0\]" must be finite'):
        decode(frame)
