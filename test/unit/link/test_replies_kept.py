"""Issue #20, the protocol keeps its word on replies: a request's answer is taken only when it
is of the request's epoch and names the request in ``reply_to``; an answer that is rejected
(malformed, too large, of another epoch, without ``reply_to``) fails its request at once with
the reason, instead of a wait of the whole timeout; a client whose server goes away says at
most one plain line. On 127.0.0.1 with ephemeral ports; timeouts are safety nets only."""
import json
import logging

import pytest
from websockets.datastructures import Headers
from websockets.exceptions import InvalidStatus
from websockets.http11 import Response

from ros_hrc.link.protocol import Ack, Decision, DispatchTable, Observation, Reset
from ros_hrc.link.transport import (LinkTimeout, MessageClient, MessageServer, ReplyRejected,
                                    connect_failure)

SAFETY = 20.0   # seconds; an old client waited this long for an answer that never came
FAST_BACKOFF = (0.01, 0.1)
BELIEF = [0.05, 0.0, 0.7, 0.25, 0.0, 0.0, 0.0]


def planner(answer):
    """A POMDP server that answers each observation with the raw frame ``answer(msg)``."""
    table = DispatchTable("fake_pomdp")

    def on_observation(msg, peer):
        peer.send_text(answer(msg))
        return None
    table.on(Observation, on_observation)
    table.on(Reset, lambda msg, peer: Ack(step=0, of=msg.type, epoch=msg.epoch + 1))
    return table


@pytest.fixture
def ask():
    made = []

    def ask(answer, request=None):
        server = MessageServer(0, planner(answer), name="fake_pomdp").start()
        client = MessageClient(server.url, "hrc_obs", backoff=FAST_BACKOFF).connect(SAFETY)
        made.append((server, client))
        request = request or Observation(step=3, observation="O35", bits=35, state="S2",
                                         epoch=7)
        return client.request(request, SAFETY)

    yield ask
    for server, client in made:
        client.close()
        server.stop()


def decision(msg, **fields):
    text = {"type": "decision", "step": msg.step, "action": "rPoint_obj", "belief": BELIEF,
            "epoch": msg.epoch, "reply_to": msg.id}
    text.update(fields)
    return json.dumps({k: v for k, v in text.items() if v is not None})


def test_a_decision_of_the_request_s_epoch_is_the_answer(ask):
    reply = ask(lambda msg: decision(msg))
    assert isinstance(reply, Decision) and reply.epoch == 7 and reply.action == "rPoint_obj"


@pytest.mark.parametrize("epoch", [8, 6, None])
def test_a_decision_of_another_epoch_with_the_right_reply_to_is_not_taken(ask, epoch):
    """Issue #20: an injected rPoint_obj of the wrong epoch moved the robot."""
    with pytest.raises(ReplyRejected) as caught:
        ask(lambda msg: decision(msg, epoch=epoch))
    assert "epoch" in str(caught.value) and "7" in str(caught.value)


def test_a_reset_ack_of_another_epoch_is_not_taken(ask):
    with pytest.raises(ReplyRejected):
        ask(None, Reset(reason="test", epoch=7))


@pytest.mark.parametrize("fields, why", [
    ({"belief": [0.25, 0.25, 0.0, 0.0, 0.0, 0.0, 0.0]}, "belief"),        # sums to 0.5
    ({"rule": "x" * 70_000}, "too large"),                                # over 64 KiB
    ({"action": 42}, "action"),
])
def test_a_rejected_decision_fails_its_request_at_once_with_the_reason(ask, fields, why):
    """Issue #20: the step waited the whole 120 s, then said "no message"."""
    with pytest.raises(ReplyRejected) as caught:
        ask(lambda msg: decision(msg, **fields))
    assert why in str(caught.value)
    assert not isinstance(caught.value, LinkTimeout)


def test_a_decision_without_reply_to_fails_its_request_at_once(ask):
    with pytest.raises(ReplyRejected) as caught:
        ask(lambda msg: decision(msg, reply_to=None))
    assert "without reply_to" in str(caught.value)


def test_a_refused_handshake_is_one_plain_line():
    """Issue #20: shutdown printed websocket's "Handshake status 503" with every header."""
    exc = InvalidStatus(Response(
        503, "Service Unavailable",
        Headers({"date": "today", "connection": "close", "content-length": "31"}),
        b"hrc_robot is stopping\n"))
    text = connect_failure(exc)
    assert text == "the server is stopping (HTTP 503)"
    assert "Handshake" not in text and "{" not in text and "\n" not in text


def test_a_client_whose_server_stops_says_at_most_one_plain_line(caplog):
    server = MessageServer(0, DispatchTable("hrc_robot"), name="hrc_robot").start()
    client = MessageClient(server.url, "hrc_human", backoff=FAST_BACKOFF).connect(SAFETY)
    caplog.set_level(logging.INFO, logger="ros_hrc.link")
    try:
        server.stop()
        # let it try to reconnect a few times (each attempt is refused)
        deadline_hit = not client._closed.wait(1.0)
        assert deadline_hit
    finally:
        client.close()
    lines = [r.getMessage() for r in caplog.records
             if r.name.startswith("ros_hrc.link.hrc_human") and r.levelno >= logging.INFO]
    assert len(lines) <= 1, lines
    assert all("Handshake" not in line and "{" not in line for line in lines), lines
