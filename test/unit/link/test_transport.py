"""The websocket transport on 127.0.0.1 with ephemeral ports: real websockets servers and
clients. Waits carry generous timeouts only as safety nets: no assertion
depends on how fast anything is."""
import threading
from dataclasses import replace

import pytest

from ros_hrc.errors import LinkError, ProtocolError
from ros_hrc.link.protocol import (ERR_FAILED, MAX_MESSAGE_BYTES, Ack, Error, Hello, Message,
                                   NextState, Observation, Reset, Step, decode, encode)
from ros_hrc.link.transport import (FRAME_LIMIT_BYTES, LinkClosed, LinkDropped, LinkTimeout,
                                    MessageClient, MessageServer, Peer, link_url)

from raw_client import RawConnection

SAFETY = 10.0  # seconds; only ever reached when something is broken
FAST_BACKOFF = (0.01, 0.1)


class Recorder:
    """A handler that acks steps and records every message it was given."""

    def __init__(self):
        self.seen = []
        self.connected = []
        self.disconnected = []
        self.changed = threading.Condition()

    def __call__(self, msg: Message, peer: Peer):
        with self.changed:
            self.seen.append(msg)
            self.changed.notify_all()
        if isinstance(msg, Step):
            return Ack(step=msg.step, of=msg.type, action="rIdle")
        if isinstance(msg, Reset):
            return Ack(step=0, of=msg.type)
        if isinstance(msg, Observation):
            raise RuntimeError("planner exploded")
        return None

    def on_connect(self, peer):
        with self.changed:
            self.connected.append(peer.who)
            self.changed.notify_all()

    def on_disconnect(self, peer):
        with self.changed:
            self.disconnected.append(peer.who)
            self.changed.notify_all()

    def wait_until(self, predicate):
        with self.changed:
            assert self.changed.wait_for(predicate, SAFETY)


@pytest.fixture
def recorder():
    return Recorder()


@pytest.fixture
def server(recorder):
    srv = MessageServer(0, recorder, name="test-server", on_connect=recorder.on_connect,
                        on_disconnect=recorder.on_disconnect)
    srv.start()
    yield srv
    srv.stop()


@pytest.fixture
def client(server):
    cli = MessageClient(server.url, "test-client", backoff=FAST_BACKOFF)
    cli.connect(SAFETY)
    # The client side of the handshake may finish first: wait until the server knows it too.
    assert server.wait_for_client(SAFETY, who="test-client")
    yield cli
    cli.close()


def bare(msg):
    """The message without its envelope (request() stamps ids; replies carry reply_to)."""
    return replace(msg, epoch=None, id=None, reply_to=None)


def raw_connection(server):
    """A bare websocket connection, able to send what MessageClient never would."""
    return RawConnection(server.url, SAFETY)


def test_server_binds_loopback_by_default_on_an_ephemeral_port(server):
    assert server.host == "127.0.0.1" and server.port > 0
    assert server.url == link_url(server.port) == f"ws://127.0.0.1:{server.port}"


def test_client_and_server_exchange_messages_both_ways(server, client, recorder):
    reply = client.request(Step(3, "idle", "evaluating"), timeout=SAFETY)
    assert reply == Ack(step=3, of="step", action="rIdle", reply_to=recorder.seen[0].id)
    assert [bare(m) for m in recorder.seen] == [Step(3, "idle", "evaluating")]
    assert recorder.seen[0].id is not None  # request() stamped a correlation id

    assert server.send(NextState(4)) == 1
    assert client.receive(SAFETY) == NextState(4)


def test_hello_introduces_each_side_and_is_not_given_to_the_handler(server, client, recorder):
    assert server.wait_for_client(SAFETY, who="test-client")
    assert [p.who for p in server.clients()] == ["test-client"]
    recorder.wait_until(lambda: recorder.connected == ["test-client"])
    client.request(Reset(), timeout=SAFETY)  # by now the server's hello has arrived too
    assert client.server_hello == Hello(who="test-server")
    assert not any(isinstance(m, Hello) for m in recorder.seen)
    assert server.send(NextState(None), who="someone-else") == 0


def test_handler_may_reply_through_the_peer_as_well_as_by_returning(recorder):
    def handler(msg, peer):
        peer(Ack(step=msg.step, of="first"))
        peer.send(Ack(step=msg.step, of="second"))

    with MessageServer(0, handler, name="peer-replies") as srv, \
            MessageClient(srv.url, "c", backoff=FAST_BACKOFF) as cli:
        cli.send(Step(1, "idle", "tired"))
        assert [cli.receive(SAFETY).of for _ in range(2)] == ["first", "second"]


MALFORMED_FRAMES = [
    ("text", "{not json", "invalid JSON"),
    ("text", "[1, 2, 3]", "must be a JSON object"),
    ("text", '{"type":"teleport","step":2}', 'unknown message type "teleport"'),
    ("text", '{"type":"step","step":2,"action":"idle"}', 'missing field "state"'),
    ("text", '{"type":"observation","step":2,"observation":"O99","bits":199,"state":"S1"}',
     '"bits" must be in 0..127'),
    ("text", '{"type":"action","step":2,"action":"rIdle","belief":[0.9,0.9]}', "must sum to 1"),
    ("binary", b'{"type":"reset"}', "binary frame"),
]


@pytest.mark.parametrize("kind,frame,words", MALFORMED_FRAMES,
                         ids=[w for _, _, w in MALFORMED_FRAMES])
def test_malformed_frame_gets_an_error_reply_and_the_connection_keeps_working(
        server, recorder, kind, frame, words):
    ws = raw_connection(server)
    try:
        ws.send(frame)   # bytes go in a binary frame
        reply = decode(ws.recv())
        assert isinstance(reply, Error) and words in reply.message
        assert recorder.seen == []  # the handler never saw it: nothing half-applied

        ws.send(encode(Step(5, "idle", "tired")))
        assert decode(ws.recv()) == Ack(step=5, of="step", action="rIdle")
        assert recorder.seen == [Step(5, "idle", "tired")]
    finally:
        ws.close()


def test_error_reply_names_the_rejected_type_and_step(server):
    ws = raw_connection(server)
    try:
        ws.send('{"type":"action","step":7,"action":"rIdle","belief":[]}')
        reply = decode(ws.recv())
        assert (reply.in_reply_to, reply.step) == ("action", 7)
    finally:
        ws.close()


def test_handler_exception_is_answered_with_an_error_and_the_server_goes_on(server, client,
                                                                           recorder):
    reply = client.request(Observation(4, "O35", 35, "S2", epoch=6), timeout=SAFETY)
    assert isinstance(reply, Error)
    assert reply.message == "RuntimeError: planner exploded"
    assert (reply.in_reply_to, reply.step, reply.code) == ("observation", 4, ERR_FAILED)
    assert reply.reply_to == recorder.seen[-1].id and reply.epoch == 6
    assert bare(client.request(Step(5, "idle", "tired"), timeout=SAFETY)) == \
        Ack(step=5, of="step", action="rIdle")


def test_handler_returning_something_unsendable_is_answered_with_an_error():
    with MessageServer(0, lambda msg, peer: {"type": "ack"}, name="sloppy") as srv, \
            MessageClient(srv.url, "c", backoff=FAST_BACKOFF) as cli:
        reply = cli.request(Step(2, "idle", "tired"), timeout=SAFETY)
        assert isinstance(reply, Error) and "only protocol messages" in reply.message


def test_message_over_the_protocol_limit_is_answered_and_the_connection_stays(server, recorder):
    ws = raw_connection(server)
    try:
        ws.send('{"type":"reset","padding":"' + "x" * MAX_MESSAGE_BYTES + '"}')
        reply = decode(ws.recv())
        assert isinstance(reply, Error) and "too large" in reply.message
        ws.send(encode(Reset()))
        assert decode(ws.recv()) == Ack(step=0, of="reset")
    finally:
        ws.close()


def test_frame_over_the_frame_limit_closes_only_that_connection(server, client):
    ws = raw_connection(server)
    try:
        ws.send("x" * (FRAME_LIMIT_BYTES + 1))
        frames, code = ws.frames_until_closed()
        assert frames == []  # the next frame is the close
        assert code == 1009  # message too big
    finally:
        ws.vanish()
    # The server is still up for everyone else.
    assert client.request(Step(1, "idle", "tired"), timeout=SAFETY).step == 1


def test_client_refuses_to_send_an_oversized_message(client):
    with pytest.raises(ProtocolError, match="too large"):
        client.send(Reset(extra={"padding": "x" * MAX_MESSAGE_BYTES}))
    assert bare(client.request(Reset(), timeout=SAFETY)) == Ack(step=0, of="reset")


def test_client_answers_a_malformed_frame_from_the_server_with_an_error(recorder):
    def handler(msg, peer):
        recorder(msg, peer)
        if isinstance(msg, Step):
            peer.send_text("{garbage")
            return Ack(step=msg.step)
        return None

    with MessageServer(0, handler, name="garbling") as srv, \
            MessageClient(srv.url, "c", backoff=FAST_BACKOFF) as cli:
        assert bare(cli.request(Step(1, "idle", "tired"), timeout=SAFETY)) == Ack(step=1)
        recorder.wait_until(lambda: any(isinstance(m, Error) for m in recorder.seen))
        error = next(m for m in recorder.seen if isinstance(m, Error))
        assert "invalid JSON" in error.message
        assert cli.drain() == []  # the garbage never reached the client's inbox


def test_client_reconnects_when_the_server_restarts(recorder):
    first = MessageServer(0, recorder, name="first").start()
    port = first.port
    reconnected = threading.Event()
    cli = MessageClient(first.url, "c", backoff=FAST_BACKOFF,
                        on_connect=lambda: reconnected.set() if cli.connections > 1 else None)
    try:
        cli.connect(SAFETY)
        assert cli.request(Step(1, "idle", "tired"), timeout=SAFETY).step == 1

        first.stop()  # as when roslaunch respawns a process that died
        second = MessageServer(port, recorder, name="second").start()
        try:
            assert reconnected.wait(SAFETY)
            assert cli.connections == 2
            assert cli.request(Step(2, "idle", "tired"), timeout=SAFETY).step == 2
            assert second.wait_for_client(SAFETY, who="c")
        finally:
            second.stop()
    finally:
        first.stop()
        cli.close()


def test_a_send_while_the_server_is_down_goes_out_once_it_is_back(recorder):
    first = MessageServer(0, recorder, name="first").start()
    port = first.port
    cli = MessageClient(first.url, "c", backoff=FAST_BACKOFF).connect(SAFETY)
    try:
        first.stop()
        outcome = []
        sender = threading.Thread(target=lambda: outcome.append(
            cli.send(Step(9, "idle", "tired"), timeout=SAFETY)))
        sender.start()
        with MessageServer(port, recorder, name="second"):
            sender.join(SAFETY)
            assert outcome == [2]  # the number of the connection it went out on
            recorder.wait_until(lambda: Step(9, "idle", "tired") in recorder.seen)
    finally:
        first.stop()
        cli.close()


def test_a_request_whose_server_dies_fails_at_once_instead_of_waiting_out_its_timeout():
    # As when the POMDP process dies in the middle of a decision: its answer can never come.
    got_it = threading.Event()

    def swallow(msg, peer):
        got_it.set()   # and never answer
        return None

    first = MessageServer(0, swallow, name="dying").start()
    cli = MessageClient(first.url, "c", backoff=FAST_BACKOFF).connect(SAFETY)
    outcome = []

    def ask():
        try:
            cli.request(Step(4, "idle", "tired"), timeout=600.0)
        except LinkError as exc:
            outcome.append(exc)

    asker = threading.Thread(target=ask)
    try:
        asker.start()
        assert got_it.wait(SAFETY)
        first.stop()
        asker.join(SAFETY)
        assert not asker.is_alive(), "the request still waits for an answer that cannot come"
        assert len(outcome) == 1 and isinstance(outcome[0], LinkDropped)
    finally:
        first.stop()
        cli.close()


def test_receive_on_a_connection_that_was_replaced_fails_but_earlier_replies_are_kept(recorder):
    first = MessageServer(0, recorder, name="first").start()
    port = first.port
    cli = MessageClient(first.url, "c", backoff=FAST_BACKOFF).connect(SAFETY)
    try:
        number = cli.send(Step(1, "idle", "tired"))
        assert number == 1
        # The ack arrived before the drop: it is still given out.
        assert cli.receive(SAFETY, match=lambda m: isinstance(m, Ack), connection=number).step == 1
        first.stop()
        with MessageServer(port, recorder, name="second") as second:
            assert second.wait_for_client(SAFETY, who="c")  # so the client is on connection 2
            with pytest.raises(LinkDropped):
                cli.receive(SAFETY, connection=number)
            assert cli.send(Step(2, "idle", "tired")) == 2
    finally:
        first.stop()
        cli.close()


def test_a_client_that_vanishes_without_closing_does_not_disturb_the_server(server, client,
                                                                             recorder):
    ws = raw_connection(server)
    ws.send(encode(Hello(who="doomed")))
    assert server.wait_for_client(SAFETY, who="doomed")
    ws.vanish()  # as when its process is killed: no close frame
    recorder.wait_until(lambda: "doomed" in recorder.disconnected)
    assert client.request(Step(1, "idle", "tired"), timeout=SAFETY).step == 1


def test_client_waits_for_a_server_that_starts_later(recorder):
    srv = MessageServer(0, recorder, name="late").start()
    port = srv.port
    srv.stop()  # the port is known, nobody listens yet
    cli = MessageClient(link_url(port), "early", backoff=FAST_BACKOFF).start()
    try:
        assert not cli.connected
        late = MessageServer(port, recorder, name="late").start()
        try:
            cli.connect(SAFETY)
            assert cli.request(Step(1, "idle", "tired"), timeout=SAFETY).step == 1
        finally:
            late.stop()
    finally:
        cli.close()


def test_connect_gives_up_at_its_deadline_and_can_be_asked_again(recorder):
    srv = MessageServer(0, recorder, name="gone").start()
    port = srv.port
    srv.stop()
    cli = MessageClient(link_url(port), "patient", backoff=FAST_BACKOFF)
    try:
        with pytest.raises(LinkTimeout):
            cli.connect(timeout=0.05)
        with pytest.raises(TimeoutError):  # a LinkTimeout is also a TimeoutError
            cli.send(Reset(), timeout=0.05)
        with MessageServer(port, recorder, name="back"):
            cli.connect(SAFETY)
            assert cli.connected
    finally:
        cli.close()


def test_server_tells_who_connected_and_who_left(server, recorder):
    cli = MessageClient(server.url, "visitor", backoff=FAST_BACKOFF).connect(SAFETY)
    recorder.wait_until(lambda: recorder.connected == ["visitor"])
    cli.close()
    recorder.wait_until(lambda: recorder.disconnected == ["visitor"])
    assert server.clients() == []  # updated before on_disconnect runs


def test_receive_times_out_and_close_wakes_a_waiting_receiver(client):
    with pytest.raises(LinkTimeout):
        client.receive(timeout=0.01)
    outcome = []
    waiter = threading.Thread(target=lambda: outcome.append(_receive_or_error(client)))
    waiter.start()
    client.close()
    waiter.join(SAFETY)
    assert isinstance(outcome[0], LinkClosed)
    with pytest.raises(LinkClosed):
        client.send(Reset())


def _receive_or_error(client):
    try:
        return client.receive()
    except LinkError as exc:
        return exc


def test_receive_with_a_match_leaves_other_messages_in_order(server, client):
    for msg in (NextState(1), Reset(), NextState(2)):
        server.send(msg)
    assert client.receive(SAFETY, match=lambda m: isinstance(m, Reset)) == Reset()
    assert client.receive(SAFETY) == NextState(1)
    assert client.receive(SAFETY) == NextState(2)


def test_many_threads_can_send_on_one_client(server, client, recorder):
    def sender(base):
        for i in range(20):
            client.send(Step(base + i, "idle", "tired"))

    threads = [threading.Thread(target=sender, args=(100 * k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(SAFETY)
    recorder.wait_until(lambda: len(recorder.seen) == 80)
    assert sorted(m.step for m in recorder.seen) == sorted(100 * k + i for k in range(4)
                                                          for i in range(20))


def test_binding_a_port_in_use_is_a_link_error(server, recorder):
    with pytest.raises(LinkError, match="cannot listen"):
        MessageServer(server.port, recorder, name="second").start()


def test_wait_for_client_is_false_when_nobody_comes(server):
    assert server.wait_for_client(timeout=0.01) is False
