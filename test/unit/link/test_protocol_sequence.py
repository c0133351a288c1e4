"""The protocol's words for a sequence of tasks (issue #30): task_end, task_report and the
reset's task fields are validated like every other message, and an older peer that sends
none of them still works."""
import pytest

from ros_hrc.link.protocol import (ERR_UNKNOWN_TYPE, Ack, DispatchTable, Error, MessageError,
                                   Observation, Reset, TaskEnd, TaskReport, decode, encode,
                                   is_reply_to)


def refused(frame):
    with pytest.raises(MessageError) as info:
        decode(frame)
    return str(info.value)


@pytest.mark.parametrize("frame, words", [
    ('{"type":"task_end","task_index":0,"outcome":"success","warnings":0,"preemptions":0,'
     '"steps":1,"duration":1,"utility":1}', 'field "task_index" must be in 1..'),
    ('{"type":"task_end","task_index":1,"outcome":"","warnings":0,"preemptions":0,'
     '"steps":1,"duration":1,"utility":1}', 'field "outcome" must not be empty'),
    ('{"type":"task_end","task_index":1,"outcome":"fail","warnings":-1,"preemptions":0,'
     '"steps":1,"duration":1,"utility":1}', 'field "warnings" must be in 0..'),
    ('{"type":"task_end","task_index":1,"outcome":"fail","warnings":0,"preemptions":0,'
     '"steps":1,"duration":-2,"utility":1}', 'field "duration" must be >= 0.0'),
    ('{"type":"task_end","task_index":1,"outcome":"fail","warnings":0,"preemptions":0,'
     '"steps":1,"duration":2}', 'utility'),
    ('{"type":"task_report","selector":"bpr","policy":"base","signature":[1,64]}',
     'field "signature[1]" must be in 0..63'),
    ('{"type":"task_report","selector":"bpr","policy":"base","type_belief":[1.0]}',
     'field "type_belief" is given without type_names'),
    ('{"type":"task_report","selector":"bpr","policy":"base","type_names":["a","b"],'
     '"type_belief":[1.0]}', 'field "type_names" has 2 names for 1 probabilities'),
    ('{"type":"task_report","selector":"bpr","policy":"base","type_names":["a","b"],'
     '"type_belief":[0.7,0.7]}', 'field "type_belief" must sum to 1'),
    ('{"type":"task_report","policy":"base"}', 'selector'),
    ('{"type":"reset","task_index":0}', 'field "task_index" must be in 1..'),
    ('{"type":"reset","drift":0.5}', 'field "drift" is given without drift_to'),
    ('{"type":"reset","drift_to":"tired","drift":1.5}', 'field "drift" must be at most 1'),
    ('{"type":"reset","human_model":""}', 'field "human_model" must not be empty'),
])
def test_a_bad_sequence_field_is_refused_naming_it(frame, words):
    assert words in refused(frame)


def test_an_older_peers_reset_is_still_a_reset_and_a_new_one_round_trips():
    assert decode('{"type":"reset","episode":3,"epoch":9}') == Reset(episode=3, epoch=9)
    new = Reset(episode=3, task_index=2, true_type="tired", human_model="tired", epoch=9)
    assert decode(encode(new)) == new
    assert '"drift"' not in encode(new)


def test_a_task_report_answers_its_task_end():
    end = TaskEnd(task_index=1, outcome="success", warnings=0, preemptions=0, steps=4,
                  duration=7.5, utility=0.95, id=5)
    assert is_reply_to(TaskReport("bpr", "base", reply_to=5), end)
    assert not is_reply_to(TaskReport("bpr", "base", reply_to=6), end)
    bare = TaskEnd(task_index=1, outcome="success", warnings=0, preemptions=0, steps=4,
                   duration=7.5, utility=0.95)
    assert is_reply_to(TaskReport("bpr", "base"), bare)
    assert not is_reply_to(TaskReport("bpr", "base"), Observation(0, "O0", 0, "S0"))


def test_an_older_planner_answers_task_end_with_unknown_type():
    # A POMDP process that knows no sequence (its table has no task_end): the coordinator
    # gets an error, not silence, and publishes the task status without the robot's part.
    table = DispatchTable("old_pomdp")
    table.on(Reset, lambda msg, peer: Ack(0, of="reset"))
    answer = table(TaskEnd(task_index=1, outcome="fail", warnings=0, preemptions=0, steps=2,
                           duration=69.0, utility=-0.43, id=3))
    assert isinstance(answer, Error) and answer.code == ERR_UNKNOWN_TYPE
    assert answer.reply_to == 3
