"""Issue #14 on the links, each failure a hostile user found, on 127.0.0.1 with ephemeral
ports: anyone could drive a server (now a launch token is proved in the hello, both ways); a
malformed `error` was answered; fields that reach a ROS message were not bounded; the accept
loop died when the process ran out of file descriptors. Timeouts are safety nets only."""
import contextlib
import json
import logging

import pytest
from websockets.exceptions import ConnectionClosed

from ros_hrc.link.protocol import (ERR_INVALID, ERR_UNAUTHORIZED, MAX_UINT32, Ack, Action,
                                   DispatchTable, Error, Hello, MessageError, Reset, Step,
                                   decode, encode)
from ros_hrc.link.token import new_nonce, proof
from ros_hrc.link.transport import CLOSE_REFUSED, LinkTimeout, MessageClient, MessageServer

from raw_client import RawConnection

SAFETY = 10.0
FAST_BACKOFF = (0.01, 0.1)


class Robot:
    """A robot port: every action it is given is carried out (and remembered)."""

    def __init__(self, token, hello_timeout=10.0):
        self.actions = []
        table = DispatchTable("hrc_robot")
        table.on(Action, self.act)
        table.on(Reset, lambda msg, peer: Ack(step=0, of=msg.type))
        self.server = MessageServer(0, table, name="hrc_robot", token=token,
                                    hello_timeout=hello_timeout)

    def act(self, msg, peer):
        self.actions.append(msg.action)
        return Ack(step=msg.step, of=msg.type, action=msg.action, success=True, result="done")


def raw(server):
    return RawConnection(server.url, SAFETY)


def frames_until_closed(ws):
    """Every frame the server sends until it closes: [text], then the close code."""
    return ws.frames_until_closed()


def client_hello(token, port, who="hrc_human", nonce=None):
    nonce = nonce or new_nonce()
    return Hello(who=who, nonce=nonce, auth=proof(token, "client", port, who, nonce))


# -- the token ------------------------------------------------------------------------------

def test_without_the_token_nobody_drives_the_robot(link_token):
    """Before: {"type":"action","action":"rGrasp_obj"} on the robot port grasped the object."""
    node = Robot(link_token[0])
    with node.server:
        ws = raw(node.server)
        ws.send(json.dumps({"type": "hello", "who": "intruder", "version": 2}))
        ws.send(json.dumps({"type": "action", "step": 0, "action": "rGrasp_obj", "id": 3}))
        got, code = frames_until_closed(ws)
    assert code == CLOSE_REFUSED and node.actions == []
    assert len(got) == 1
    refusal = decode(got[0])
    assert isinstance(refusal, Error) and refusal.code == ERR_UNAUTHORIZED
    assert refusal.message.startswith("hrc_robot: refused: a hello without a proof of the link "
                                      "token")


def test_an_action_before_the_hello_is_refused_and_nothing_acts(link_token):
    node = Robot(link_token[0])
    with node.server:
        ws = raw(node.server)
        ws.send(json.dumps({"type": "action", "step": 0, "action": "rGrasp_obj", "id": 4}))
        got, code = frames_until_closed(ws)
    assert code == CLOSE_REFUSED and node.actions == []
    refusal = decode(got[0])
    assert refusal.code == ERR_UNAUTHORIZED and refusal.reply_to == 4
    assert "a action message before its hello" in refusal.message


@pytest.mark.parametrize("forge", ["wrong token", "other port", "other name", "no nonce"])
def test_a_forged_proof_is_refused(forge, link_token):
    token = link_token[0]
    node = Robot(token)
    with node.server:
        port = node.server.port
        hello = {"wrong token": client_hello("ab" * 32, port),
                 "other port": client_hello(token, port + 1),
                 "other name": Hello(who="intruder", nonce=(n := new_nonce()),
                                     auth=proof(token, "client", port, "hrc_human", n)),
                 "no nonce": Hello(who="hrc_human", auth="0" * 64)}[forge]
        ws = raw(node.server)
        ws.send(encode(hello))
        # The server may have refused the hello and closed before this frame leaves (seen
        # once, under load): the action then never reaches it, which is as refused.
        with contextlib.suppress(ConnectionClosed):
            ws.send(encode(Action(step=0, action="rGrasp_obj")))
        got, code = frames_until_closed(ws)
    assert code == CLOSE_REFUSED and node.actions == []
    assert [decode(g).code for g in got] == [ERR_UNAUTHORIZED]


def test_a_replayed_hello_is_refused(link_token):
    token = link_token[0]
    node = Robot(token)
    with node.server:
        hello = encode(client_hello(token, node.server.port))
        first = raw(node.server)
        first.send(hello)
        answer = decode(first.recv())
        assert isinstance(answer, Hello) and answer.who == "hrc_robot"
        again = raw(node.server)
        again.send(hello)
        got, code = frames_until_closed(again)
        first.close()
    assert code == CLOSE_REFUSED and "nonce was used before" in decode(got[0]).message


def test_the_launch_s_client_is_served_and_the_server_proves_the_token(link_token):
    token = link_token[0]
    node = Robot(token)
    with node.server, MessageClient(node.server.url, "hrc_human", token=token,
                                    backoff=FAST_BACKOFF) as client:
        reply = client.request(Action(step=0, action="rPoint_obj"), timeout=SAFETY)
        assert isinstance(reply, Ack) and reply.success
        hello = client.server_hello
        assert hello.who == "hrc_robot" and hello.auth is not None
    assert node.actions == ["rPoint_obj"]


def test_a_client_with_another_launch_s_token_is_refused_and_says_so_once(link_token, caplog):
    node = Robot(link_token[0])
    with node.server:
        client = MessageClient(node.server.url, "hrc_human", token="cd" * 32,
                               backoff=FAST_BACKOFF)
        try:
            with caplog.at_level(logging.INFO, logger="ros_hrc.link"):
                with pytest.raises(LinkTimeout):
                    client.connect(timeout=1.0)
        finally:
            client.close()
    assert node.actions == []
    said = [r.getMessage() for r in caplog.records if "refused our link token" in r.getMessage()]
    assert len(said) == 1, said
    assert "hrc_robot: refused: a hello with a wrong proof of the link token" in said[0]


def test_a_client_never_takes_a_server_that_cannot_prove_the_token(link_token, caplog):
    """A process that took the port before the stack (here: a server with another token, or
    none) gets no request: the client refuses it."""
    impostor = Robot(None).server.start()
    try:
        client = MessageClient(impostor.url, "hrc_human", token=link_token[0],
                               backoff=FAST_BACKOFF)
        try:
            with pytest.raises(LinkTimeout):
                client.connect(timeout=1.0)
        finally:
            client.close()
    finally:
        impostor.stop()
    assert any("did not prove it knows the link token" in r.getMessage()
               for r in caplog.records)


def test_a_silent_connection_is_refused_after_the_hello_timeout(link_token):
    node = Robot(link_token[0], hello_timeout=0.3)
    with node.server:
        ws = raw(node.server)
        got, code = frames_until_closed(ws)
    assert code == CLOSE_REFUSED
    assert "no hello within 0.3 s" in decode(got[0]).message


def test_a_flood_of_refusals_is_logged_at_most_once_a_second(link_token, caplog):
    node = Robot(link_token[0])
    with node.server, caplog.at_level(logging.WARNING, logger="ros_hrc.link"):
        for _ in range(30):
            ws = raw(node.server)
            ws.send('{"type":"hello","who":"x"}')
            frames_until_closed(ws)
    lines = [r for r in caplog.records if "refused a client" in r.getMessage()]
    assert 1 <= len(lines) <= 3


# -- an error is never answered ---------------------------------------------------------------

@pytest.mark.parametrize("frame", [
    '{"type":"error","message":"\\ud800"}',                      # a lone surrogate
    '{"type":"error","message":"x","message":"y"}',               # a repeated key
    '{"type":"error","message":"x",',                             # cut short
    '{"type":"error","message":"x","step":1e999}',                # not finite
    '{"type":"error","message":"line\\nbreak"}',                  # a control character
    '{"type": "error", "message": 5}',                            # a wrong type
])
def test_a_malformed_error_is_never_answered(frame):
    """Before: a lone surrogate in an error's message was answered with an error."""
    node = Robot(None)
    with node.server:
        ws = raw(node.server)
        ws.send(encode(Hello(who="peer")))
        decode(ws.recv())
        ws.send(frame)
        ws.send(encode(Reset(id=9)))    # the next answer is the reset's, not the error's
        answer = decode(ws.recv())
        ws.close()
    assert isinstance(answer, Ack) and answer.reply_to == 9


def test_decode_says_a_rejected_frame_was_an_error_when_it_shows_it():
    for frame in ('{"type":"error","message":"\\ud800"}', '{"type":"error"', b'"type":"error"'):
        with pytest.raises(MessageError) as caught:
            decode(frame)
        assert caught.value.msg_type == "error"


# -- fields are bounded before anything acts --------------------------------------------------

@pytest.mark.parametrize("change,words", [
    ({"step": 2 ** 40}, '"step" must be in 0..4294967295'),
    ({"state_index": 300}, '"state_index" must be in 0..255'),
    ({"epoch": MAX_UINT32 + 1}, '"epoch" must be in 0..4294967295'),
    ({"action": "idle\x1b[2J"}, '"action" must not hold control characters, has U+001B'),
    ({"state": "x" * 129}, '"state" must be at most 128 characters'),
    ({"belief": {"tired\n": 1.0}}, "must not hold control characters"),
    ({"note": 1e999}, '"note" must be finite'),
    ({"note": {"deep": [1, float("inf")]}}, '"note.deep[1]" must be finite'),
])
def test_a_step_out_of_the_ros_messages_ranges_is_refused_before_it_acts(change, words):
    """Before: state_index 300 and step 2**40 failed in a uint8 / uint32 of /hrc/status after
    the human's action already ran."""
    frame = json.dumps({"type": "step", "step": 1, "action": "idle", "state": "tired", **change})
    frame = frame.replace("Infinity", "1e999")   # an overflowing literal reads as infinity
    with pytest.raises(MessageError) as caught:
        decode(frame)
    assert words in caught.value.reason and caught.value.code == ERR_INVALID


def test_a_reset_reason_with_a_lone_surrogate_or_a_control_character_is_refused():
    with pytest.raises(MessageError, match="lone surrogate"):
        decode('{"type":"reset","reason":"\\ud800"}')
    with pytest.raises(MessageError, match='"reason" must not hold control characters'):
        decode('{"type":"reset","reason":"a\\u0007b"}')
    with pytest.raises(MessageError, match='"reason" must be at most 1024 characters'):
        decode(json.dumps({"type": "reset", "reason": "r" * 1025}))


def test_texts_this_side_writes_are_made_sendable():
    from ros_hrc.link.protocol import error_message
    msg = error_message(RuntimeError("two\nlines\x1b[0m and \ud800"))
    assert "\n" not in msg.message and "\x1b" not in msg.message
    assert decode(encode(msg)).message == msg.message


# -- found by the fuzz test (test/rostest/test_fuzz.py) ----------------------------------------

@pytest.mark.parametrize("frame", [
    '{"type":"reset","epoch":4294967296}',
    '{"type":"action","step":4294967296,"action":"rPoint_obj"}',
    '{"type":"next_state","state":null,"epoch":9007199254740991}',
    '{"type":"step","step":' + "9" * 4300 + ',"action":"idle","state":"tired"}',
])
def test_a_frame_out_of_range_is_answered_not_dropped_with_the_connection(frame):
    """Before: the error answering it copied the out-of-range step or epoch, could not be built
    (MessageError in the connection handler) and the connection closed with 1011."""
    from ros_hrc.link.protocol import error_reply
    with pytest.raises(MessageError) as caught:
        decode(frame)
    reply = decode(error_reply(caught.value))
    assert isinstance(reply, Error) and reply.code == ERR_INVALID
    node = Robot(None)
    with node.server:
        ws = raw(node.server)
        ws.send(frame)
        answer = decode(ws.recv())
        ws.send(encode(Reset(id=5)))
        after = decode(ws.recv())
        ws.close()
    assert answer.code == ERR_INVALID and after.reply_to == 5


def test_a_belief_of_huge_numbers_names_its_field():
    """Before: 'cannot decode the frame: OverflowError: intermediate overflow in fsum'."""
    with pytest.raises(MessageError, match=r'"belief\[0\]" must be at most 1, got 1e\+308'):
        decode('{"type":"action","step":0,"action":"rIdle","belief":[1e308,1e308]}')


def test_a_second_hello_does_not_rename_the_client(link_token):
    """Before: a second hello on an authenticated connection renamed the peer."""
    token = link_token[0]
    node = Robot(token)
    with node.server:
        ws = raw(node.server)
        ws.send(encode(client_hello(token, node.server.port, who="hrc_human")))
        decode(ws.recv())
        ws.send(encode(Hello(who="someone_else", id=2)))
        answer = decode(ws.recv())
        names = [peer.who for peer in node.server.clients()]
        ws.close()
    assert answer.code == "refused" and answer.reply_to == 2
    assert "said hello already, as 'hrc_human'" in answer.message
    assert names == ["hrc_human"]
