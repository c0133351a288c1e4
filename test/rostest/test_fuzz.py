#!/usr/bin/env python3
"""The two link servers under a fuzzer (issue #14), on one real stack: `roslaunch ros_hrc
hrc.launch` headless, stepping on its own (on_episode_end:=reset, step_delay 0.1), started by
the test against this test's master, on free ports of its own.

A seeded, bounded generator (fuzz_frames.py: random bytes, random text, truncated and
corrupted JSON, every message type mutated, malformed errors, out-of-range envelopes,
oversized messages and frames, ...) gives :data:`FRAMES_PER_PORT` frames per port, more than
10,000 in all, sent to the POMDP process (pomdp_port) and hrc_human (human_port) at once, one
thread per port (hrc_robot's robot_port, the third link, is gone: hrc_human calls the world's
/robot/* services itself):

* **unauthenticated** connections, interleaved with the rest: 1 to 3 fuzz frames sent before,
  or instead of, a hello that proves the link token (plus, per port, a replayed hello, a proof
  made for another port, a proof of the server's role, a proving hello in a binary frame).
  Every one must be refused and closed: the only frame a server may send on it is one
  ``error`` with code ``unauthorized`` (none when the first frame is itself an ``error``), and
  then a close (1008; 1009 when the first frame is over the frame limit, 1007 when it is not
  UTF-8). Anything else is a failure.
* **authenticated** connections (our hello proves the token; the server's hello must prove it
  back): fuzz frames in batches, each batch followed by a probe (``{"type":"fuzz_probe"}``,
  which every server answers with an ``unknown_type`` error) so the replies can be paired
  with the frames without waiting for each one. On the POMDP port the replies of
  a batch must be exactly those the protocol says (what the frame is comes from
  ros_hrc.link.protocol's own ``decode``): one per frame, none for an ``error`` (well formed
  or not), one ``refused`` error for a second hello; a rejected frame gets an ``invalid`` or
  ``unknown_type`` error; every reply is a valid message. A frame over 256 KiB or not UTF-8
  ends a batch, the server must close that connection, and the next batch goes on a new one.
  On the human port every authenticated client but the served MDP is refused once its hello
  is taken (the server hello, then an ``error`` ``seat_taken``, then a close 1008), so each
  connection there carries one batch, read by the server until the refusal lands.

Afterwards: every server still accepts an authenticated hello and proves the token in its
answer (and answers a probe; the human port refuses the seat instead, which shows it is up
too); the loop publishes at least 3 new fault-free steps on /hrc/status (it may have reset:
fuzzed resets and observations of other epochs on the POMDP port are accepted
requests, and the loop must recover from them); none of the launch's four processes (the two
nodes and both solver processes, found by ``__name:=`` under roslaunch) has died or been
respawned (same PIDs before and after); and no traceback appeared in the launch's output
while the fuzz ran.

The counts (printed in one block, to stdout and to ``$ROS_LOG_DIR/fuzz_counts.txt``), per port
and in total:

frames    fuzz frames sent (our own proving hellos and the probes not counted)
unauth    of which on unauthenticated connections
replies   frames the server sent back to fuzz frames (not the answers to our hellos or probes)
errors    of which ``error`` frames
conns     connections opened (unauthenticated + authenticated)
closed    connections the server closed (a close frame, or the socket ended)
survived  frames on authenticated connections after which the connection stayed open: the
          probe after them was answered
codes     close codes seen, with how often ("eof": the socket ended without a close frame)
"""
import collections
import json
import os
import random
import socket
import sys
import threading
import time
import unittest
from typing import Any, List, Optional, Tuple, Union

import rospy
import rostest
from websockets.exceptions import ConnectionClosed, WebSocketException
from websockets.frames import CloseCode
from websockets.sync.client import ClientConnection, connect

import fuzz_frames  # next to this file, as hrc_stack is
from hrc_stack import StatusLog, node_pids, start_stack, stop_stack
from ros_hrc.link.protocol import (ERR_INVALID, ERR_SEAT_TAKEN, ERR_UNAUTHORIZED,
                                   ERR_UNKNOWN_TYPE, PROTOCOL_VERSION, Error, Hello,
                                   MessageError, decode)
from ros_hrc.link.token import new_nonce, proof, read_token
from ros_hrc.link.transport import free_port

#: The fuzz's seed (HRC_FUZZ_SEED overrides it, to replay another run).
SEED = int(os.environ.get("HRC_FUZZ_SEED", "14"))
#: Fuzz frames per port (two ports: 10,800 in all). The human port's server refuses each
#: connection once it has taken its hello, and the frames still to go then are not sent: the
#: faster it refuses, the more (4,901 of 5,100 sent on a quiet machine, 9,999 in all).
FRAMES_PER_PORT = 5400
#: Bound of one port's frames together, in bytes.
BYTES_PER_PORT = 16 * 1024 * 1024
#: Fuzz frames per batch on an authenticated connection (then a probe).
BATCH = 24
#: Frames per connection on the human port (it refuses every client but the MDP's).
HUMAN_BATCH = 12
#: An unauthenticated connection about every this many frames.
UNAUTH_EVERY = 22
#: Seconds a server may take to answer a probe or to close a connection: safety nets only
#: (a batch is answered in milliseconds; a valid observation plans for ~0.05 s).
ANSWER_TIMEOUT = 20.0
#: A port's fuzzing gives up after this many seconds (it takes a few): a server that hangs
#: fails the test in time, not at rostest's time limit.
FUZZ_DEADLINE = 240.0
#: Steps the loop must publish after the fuzz, and how long it may take (a generous net).
STEPS_AFTER = 3
STEPS_WAIT = 90.0
#: The launch's processes, by their __name.
PROCESSES = ("hrc_world", "hrc_human", "despot_pomdp", "despot_mdp")
PROBE_TYPE = "fuzz_probe"
PORT_NAMES = ("pomdp", "human")
WHO = "fuzz_test"


class Stats:
    """What one port's fuzzing saw; see the module docstring for the counts."""

    def __init__(self, name: str, port: int) -> None:
        self.name, self.port = name, port
        self.frames = self.unauth = self.replies = self.errors = 0
        self.conns = self.closed = self.survived = 0
        self.codes: collections.Counter = collections.Counter()
        self.reply_codes: collections.Counter = collections.Counter()
        self.problems: List[str] = []
        self.bytes = 0

    def problem(self, text: str) -> None:
        if len(self.problems) < 200:
            self.problems.append(f"{self.name} port {self.port}: {text}")


# -- one websocket connection -----------------------------------------------------------------

class Closed(Exception):
    """The server closed the connection (``code``: its close code, None for a bare EOF)."""

    def __init__(self, code: Optional[int]) -> None:
        super().__init__(f"closed ({code})")
        self.code = code


def open_socket(port: int) -> ClientConnection:
    # No keepalive pings and no frame limit of ours: only what the fuzz sends goes out, and
    # whatever a server sends is read.
    return connect(f"ws://127.0.0.1:{port}", open_timeout=ANSWER_TIMEOUT, close_timeout=1.0,
                   compression=None, max_size=None, ping_interval=None, proxy=None,
                   legacy=True)


def hang_up(ws: ClientConnection) -> None:
    """End the connection at once, without a closing handshake."""
    try:
        ws.socket.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    ws.close()


def send_frame(ws: ClientConnection, frame: fuzz_frames.Frame) -> None:
    """Send a fuzz frame as it is: text (its bytes as they are, UTF-8 or not) or binary, in
    its fragments (websockets ends a fragmented message with an empty final fragment)."""
    if frame.fragments <= 1:
        ws.send(frame.payload, text=not frame.binary)
        return
    chunks, at = [], 0
    for size in fuzz_frames.fragment_sizes(frame):
        chunks.append(frame.payload[at:at + size])
        at += size
    ws.send(chunks, text=not frame.binary)


def read(ws: ClientConnection, timeout: float) -> Union[str, bytes]:
    """The next data message: ``str`` from a text frame, ``bytes`` from a binary one. Raises
    :class:`Closed` when the server closed the connection (with the close frame's code),
    ``TimeoutError`` when nothing came in time. websockets answers pings and keeps the close
    code the server sent."""
    try:
        return ws.recv(timeout)
    except ConnectionClosed as closed:
        code = closed.rcvd.code if closed.rcvd is not None else None
        raise Closed(None if code == CloseCode.NO_STATUS_RCVD else code) from None


def read_message(ws: ClientConnection, timeout: float, stats: Stats,
                 where: str) -> Optional[Any]:
    """The next frame from the server, decoded; a frame that is not a valid message (which no
    server may send) is a problem, and ``None``. (A text frame that is not UTF-8 fails the
    connection in websockets itself: it shows as a close.)"""
    data = read(ws, timeout)
    if isinstance(data, bytes):
        stats.problem(f"{where}: the server sent a binary frame: {data[:80]!r}")
        return None
    try:
        return decode(data)
    except MessageError as exc:
        stats.problem(f"{where}: the server sent an invalid message ({exc}): {data[:160]!r}")
        return None


def wait_closed(ws: ClientConnection, stats: Stats, where: str,
                allow_replies: int = 0) -> Tuple[Optional[int], List[Any]]:
    """Read until the server closes; (close code, messages read meanwhile). A server that does
    not close within :data:`ANSWER_TIMEOUT` is a problem."""
    messages: List[Any] = []
    deadline = time.monotonic() + ANSWER_TIMEOUT
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            stats.problem(f"{where}: the server did not close the connection within "
                          f"{ANSWER_TIMEOUT:g} s")
            return -1, messages
        try:
            msg = read_message(ws, left, stats, where)
        except Closed as closed:
            return closed.code, messages
        except TimeoutError:
            continue
        messages.append(msg)


def hello_frame(token: str, port: int, nonce: Optional[str] = None, who: str = WHO,
                role: str = "client", proof_port: Optional[int] = None) -> Tuple[str, str]:
    """(a hello proving the token, its nonce)."""
    nonce = nonce or new_nonce()
    auth = proof(token, role, proof_port or port, who, nonce)
    return json.dumps({"type": "hello", "who": who, "version": PROTOCOL_VERSION,
                       "nonce": nonce, "auth": auth}), nonce


def server_proves(msg: Any, token: str, port: int, nonce: str) -> bool:
    return (isinstance(msg, Hello) and isinstance(msg.auth, str)
            and msg.auth == proof(token, "server", port, msg.who, nonce))


def code_name(code: Optional[int]) -> str:
    return "eof" if code is None else ("timeout" if code == -1 else str(code))


# -- what the protocol says a server answers -------------------------------------------------

def expected_replies(frame: fuzz_frames.Frame) -> Optional[int]:
    """Replies the server of the POMDP port sends an authenticated client for
    ``frame``: None when it closes the connection instead."""
    if frame.closes:
        return None
    try:
        msg = decode(frame.payload if frame.binary else frame.text)
    except MessageError as exc:
        return 0 if exc.msg_type == Error.TYPE else 1
    if isinstance(msg, Error):
        return 0
    # A hello on an authenticated connection is a second hello: refused with one error.
    return 1


def rejected(frame: fuzz_frames.Frame) -> bool:
    """Whether the protocol module rejects the frame (so its one reply is an invalid or
    unknown_type error)."""
    try:
        decode(frame.payload if frame.binary else frame.text)
        return False
    except MessageError:
        return True


# -- the fuzzer of one port --------------------------------------------------------------------

class PortFuzzer:
    """Sends one port's frames: unauthenticated connections interleaved with batches on
    authenticated ones. Runs in a thread of its own."""

    def __init__(self, name: str, port: int, token: str, frames: List[fuzz_frames.Frame],
                 other_port: int, seed: int) -> None:
        self.name, self.port, self.token = name, port, token
        self.frames = frames
        self.other_port = other_port
        self.rng = random.Random(seed)
        self.stats = Stats(name, port)
        self.stats.bytes = sum(f.size for f in frames)
        self.ws: Optional[ClientConnection] = None
        self.probes = 0
        self.last_hello: Optional[str] = None
        self.error: Optional[BaseException] = None

    def run(self) -> None:
        try:
            self._run()
        except BaseException as exc:  # reported by the test
            self.error = exc
            self.stats.problem(f"the fuzzer failed: {type(exc).__name__}: {exc}")
        finally:
            self._drop()

    def _run(self) -> None:
        frames = self.frames
        i = 0
        next_unauth = self.rng.randrange(UNAUTH_EVERY)
        token_cases = ["replay", "other_port", "server_role", "binary_hello"]
        batch_size = HUMAN_BATCH if self.name == "human" else BATCH
        deadline = time.monotonic() + FUZZ_DEADLINE
        while i < len(frames):
            if time.monotonic() > deadline:
                self.stats.problem(f"gave up after {FUZZ_DEADLINE:g} s with {len(frames) - i} "
                                   "frames unsent: the server answers too slowly")
                return
            if i >= next_unauth:
                i = self._unauthenticated(i)
                next_unauth = i + self.rng.randrange(UNAUTH_EVERY // 2, UNAUTH_EVERY * 3 // 2)
                if token_cases and self.rng.random() < 0.3:
                    self._token_case(token_cases.pop())
                continue
            # A batch: up to the next unauthenticated connection, ended early by a frame
            # that closes the connection.
            batch: List[fuzz_frames.Frame] = []
            while i < len(frames) and len(batch) < batch_size and i < next_unauth:
                batch.append(frames[i])
                i += 1
                if batch[-1].closes:
                    break
            if self.name == "human":
                self._human_batch(batch)
            else:
                self._batch(batch)
        for case in token_cases:
            self._token_case(case)

    # -- unauthenticated ---------------------------------------------------------------------

    def _unauthenticated(self, i: int) -> int:
        """Send frames[i] and up to two more small ones on a connection that never proves the
        token; they must be refused and closed. Returns the index of the next frame."""
        first = self.frames[i]
        taken = [first]
        i += 1
        if not first.closes:
            for _ in range(self.rng.randrange(3)):
                if i < len(self.frames) and not self.frames[i].closes:
                    taken.append(self.frames[i])
                    i += 1
        self._refused(taken, f"unauthenticated {first.kind} ({first.note})",
                      expect_error=bool(expected_replies(first)))
        return i

    def _refused(self, frames: List[Any], where: str, expect_error: bool) -> None:
        """One connection: send ``frames`` (fuzz frames, or raw text of our own), then check
        the refusal."""
        s = self.stats
        ws = self._open(where)
        if ws is None:
            return
        try:
            for frame in frames:
                try:
                    if isinstance(frame, fuzz_frames.Frame):
                        send_frame(ws, frame)
                        s.frames += 1
                        s.unauth += 1
                    else:
                        ws.send(frame[0], text=not frame[1])
                except (WebSocketException, OSError):
                    break  # closed already
            code, messages = wait_closed(ws, s, where)
        finally:
            hang_up(ws)
        if code != -1:
            s.closed += 1
        s.codes[code_name(code)] += 1
        for msg in messages:
            s.replies += 1
            if isinstance(msg, Error):
                s.errors += 1
                s.reply_codes[msg.code] += 1
        first = frames[0]
        closing = isinstance(first, fuzz_frames.Frame) and first.closes
        if closing:
            want = {1009} if first.over_frame_limit else {1007}
            if messages or (code not in want and code is not None):
                s.problem(f"{where}: expected a close {want} and nothing else, got "
                          f"{[m.type if m else None for m in messages]} and close "
                          f"{code_name(code)}")
            return
        wanted = 1 if expect_error else 0
        ok = (len(messages) == wanted and all(isinstance(m, Error) and m.code == ERR_UNAUTHORIZED
                                              for m in messages) and code == 1008)
        if not ok:
            s.problem(f"{where}: expected {'one unauthorized error' if wanted else 'no answer'} "
                      f"and a close 1008, got "
                      f"{[(m.type, getattr(m, 'code', None)) if m else None for m in messages]} "
                      f"and close {code_name(code)}; frames: "
                      + "; ".join(f.preview(120) if isinstance(f, fuzz_frames.Frame)
                                  else repr(f[0])[:120] for f in frames))

    def _token_case(self, case: str) -> None:
        """A hello that proves nothing here, though made with the token."""
        text, binary = False, True   # (frame, binary?)
        if case == "replay" and self.last_hello:
            frames = [(self.last_hello, text)]
        elif case == "other_port":
            frames = [(hello_frame(self.token, self.port, proof_port=self.other_port)[0],
                       text)]
        elif case == "server_role":
            frames = [(hello_frame(self.token, self.port, role="server")[0], text)]
        elif case == "binary_hello":
            frames = [(hello_frame(self.token, self.port)[0].encode(), binary)]
        else:
            return
        self._refused(frames, f"token case {case}", expect_error=True)

    # -- authenticated -----------------------------------------------------------------------

    def _connect(self) -> bool:
        """An authenticated connection (the server's hello must prove the token)."""
        s = self.stats
        ws = self._open()
        if ws is None:
            return False
        hello, nonce = hello_frame(self.token, self.port)
        try:
            ws.send(hello)
            msg = read_message(ws, ANSWER_TIMEOUT, s, "our hello")
        except Closed as closed:
            s.problem(f"our proving hello was answered with a close ({code_name(closed.code)})")
            s.closed += 1
            s.codes[code_name(closed.code)] += 1
            hang_up(ws)
            return False
        except TimeoutError:
            s.problem("our proving hello was not answered")
            hang_up(ws)
            return False
        if not server_proves(msg, self.token, self.port, nonce):
            s.problem(f"the server's answer to our hello does not prove the token: {msg}")
            hang_up(ws)
            return False
        self.ws = ws
        self.last_hello = hello
        return True

    def _drop(self) -> None:
        if self.ws is not None:
            try:
                self.ws.close()   # within its close_timeout
            except (WebSocketException, OSError):
                pass
            self.ws = None

    def _probe(self, ws: ClientConnection) -> Tuple[str, int]:
        self.probes += 1
        probe_id = 7_000_000_000 + self.probes
        ws.send(json.dumps({"type": PROBE_TYPE, "id": probe_id}))
        return PROBE_TYPE, probe_id

    @staticmethod
    def _is_probe_answer(msg: Any, probe_id: int) -> bool:
        return (isinstance(msg, Error) and msg.reply_to == probe_id
                and msg.in_reply_to == PROBE_TYPE and msg.code == ERR_UNKNOWN_TYPE)

    def _batch(self, batch: List[fuzz_frames.Frame]) -> None:
        """The POMDP port: send a batch, then a probe; check the replies frame by frame.
        A frame that closes the connection goes alone, once the rest was answered (a
        connection that fails drops what it had queued), and the close is checked."""
        closing = batch[-1] if batch and batch[-1].closes else None
        if closing is not None:
            batch = batch[:-1]
        if batch:
            self._answered_batch(batch)
        if closing is not None:
            self._closing_frame(closing)

    def _answered_batch(self, batch: List[fuzz_frames.Frame]) -> None:
        s = self.stats
        if self.ws is None and not self._connect():
            return
        ws = self.ws
        sent: List[fuzz_frames.Frame] = []
        probe_id: Optional[int] = None
        try:
            for frame in batch:
                send_frame(ws, frame)
                sent.append(frame)
            probe_id = self._probe(ws)[1]
        except (WebSocketException, OSError) as exc:
            s.problem(f"a send failed ({exc}): the server closed the connection during: "
                      + self._describe(batch[:len(sent) + 1]))
        s.frames += len(sent)
        replies: List[Any] = []
        deadline = time.monotonic() + ANSWER_TIMEOUT
        while probe_id is not None:
            left = deadline - time.monotonic()
            if left <= 0:
                s.problem(f"no answer to the probe within {ANSWER_TIMEOUT:g} s after: "
                          + self._describe(sent))
                self._drop()
                return
            try:
                msg = read_message(ws, left, s, "a batch")
            except Closed as closed:
                self._lost(closed.code)
                self._count(replies)
                s.problem(f"the server closed the connection ({code_name(closed.code)}) after "
                          f"{len(sent)} frames; " + self._isolate(sent))
                return
            except TimeoutError:
                continue
            if self._is_probe_answer(msg, probe_id):
                break
            replies.append(msg)
        else:
            self._lost(None)
            return
        self._count(replies)
        s.survived += len(sent)
        self._check_replies(sent, replies)

    def _closing_frame(self, frame: fuzz_frames.Frame) -> None:
        """A frame over the frame limit (1009) or not UTF-8 (1007): the server must close."""
        s = self.stats
        if self.ws is None and not self._connect():
            return
        ws = self.ws
        try:
            send_frame(ws, frame)
        except (WebSocketException, OSError):
            pass  # the server may close before it has all of it
        s.frames += 1
        code, messages = wait_closed(ws, s, f"after {frame.kind}")
        self._count(messages)
        self._lost(code)
        want = 1009 if frame.over_frame_limit else 1007
        if messages or code not in (want, None):
            s.problem(f"expected a close {want} and nothing else, got "
                      f"{[str(m)[:100] for m in messages]} and close {code_name(code)} after "
                      + frame.preview())

    def _lost(self, code: Optional[int]) -> None:
        """The server closed our authenticated connection."""
        s = self.stats
        if code != -1:
            s.closed += 1
        s.codes[code_name(code)] += 1
        if self.ws is not None:
            hang_up(self.ws)
            self.ws = None

    def _count(self, replies: List[Any]) -> None:
        s = self.stats
        for msg in replies:
            s.replies += 1
            if isinstance(msg, Error):
                s.errors += 1
                s.reply_codes[msg.code] += 1

    def _check_replies(self, sent: List[fuzz_frames.Frame], replies: List[Any]) -> None:
        """Pair the replies with the frames, in order (a server answers one frame after the
        other, on one connection); a count that is off is looked into frame by frame."""
        expected = [expected_replies(f) or 0 for f in sent]
        if sum(expected) != len(replies):
            self.stats.problem(
                f"{len(replies)} replies to {len(sent)} frames, the protocol says "
                f"{sum(expected)}; replies: "
                f"{[(m.type, getattr(m, 'code', None)) if m else None for m in replies]}; "
                + self._isolate(sent))
            return
        at = 0
        for frame, n in zip(sent, expected):
            mine = replies[at:at + n]
            at += n
            if n and rejected(frame):
                last = mine[-1]
                if not (isinstance(last, Error) and last.code in (ERR_INVALID,
                                                                  ERR_UNKNOWN_TYPE)):
                    self.stats.problem(f"a rejected frame was answered with {last}: "
                                       + frame.preview())

    def _isolate(self, frames: List[fuzz_frames.Frame]) -> str:
        """Send the frames again one by one, each followed by a probe, on a connection of its
        own: which ones get other replies than the protocol says."""
        found = []
        self._drop()
        for frame in frames:
            if frame.closes:
                continue
            if self.ws is None and not self._connect():
                return "cannot reconnect to look into it"
            ws = self.ws
            try:
                send_frame(ws, frame)
                probe_id = self._probe(ws)[1]
                got = []
                while True:
                    msg = read_message(ws, ANSWER_TIMEOUT, self.stats, "isolating")
                    if self._is_probe_answer(msg, probe_id):
                        break
                    got.append(msg)
            except (Closed, WebSocketException, OSError) as exc:
                found.append(f"{frame.kind} {frame.preview()}: {type(exc).__name__} {exc}")
                self._drop()
                continue
            if len(got) != (expected_replies(frame) or 0):
                found.append(f"{frame.kind} ({frame.note}) {frame.preview()} -> "
                             f"{[str(m)[:200] for m in got]}")
        return "frames answered otherwise, one by one: " + (" | ".join(found) or "none")

    def _open(self, where: str = "") -> Optional[ClientConnection]:
        """A new connection to the port, counted; None (and a problem noted) if it fails."""
        try:
            ws = open_socket(self.port)
        except (WebSocketException, OSError) as exc:
            self.stats.problem(f"{where + ': ' if where else ''}cannot connect: {exc}")
            return None
        self.stats.conns += 1
        return ws

    def _describe(self, frames: List[fuzz_frames.Frame]) -> str:
        return " | ".join(f"{f.kind} ({f.note})" for f in frames)[:2000]

    def _human_batch(self, batch: List[fuzz_frames.Frame]) -> None:
        """The human port: our hello, the batch and a probe at once; the server takes frames
        until it refuses the seat (an error seat_taken, then a close 1008)."""
        s = self.stats
        ws = self._open()
        if ws is None:
            return
        hello, nonce = hello_frame(self.token, self.port)
        sent: List[fuzz_frames.Frame] = []
        try:
            ws.send(hello)
            for frame in batch:
                send_frame(ws, frame)
                sent.append(frame)
            if not (sent and sent[-1].closes):
                self._probe(ws)
        except (WebSocketException, OSError):
            pass  # the refusal came first
        s.frames += len(sent)
        code, messages = wait_closed(ws, s, "the human port's refusal")
        hang_up(ws)
        if code != -1:
            s.closed += 1
        s.codes[code_name(code)] += 1
        if not messages or not server_proves(messages[0], self.token, self.port, nonce):
            if not (sent and sent[-1].closes):
                s.problem(f"no proving server hello first: "
                          f"{[str(m)[:100] for m in messages[:2]]}")
        else:
            self.last_hello = hello
        rest = messages[1:] if messages and isinstance(messages[0], Hello) else messages
        probe_answered = any(isinstance(m, Error) and m.in_reply_to == PROBE_TYPE for m in rest)
        rest = [m for m in rest if not (isinstance(m, Error) and m.in_reply_to == PROBE_TYPE)]
        self._count(rest)
        if probe_answered:
            s.survived += len(sent)
        seat = [m for m in rest if isinstance(m, Error) and m.code == ERR_SEAT_TAKEN
                and m.in_reply_to is None]
        # The server takes frames until the refusal lands, so fewer replies may come than on
        # the other ports (and a refused step's answer may come after the close), never more.
        most = sum(expected_replies(f) or 0 for f in sent)
        if len(rest) - len(seat) > most:
            s.problem(f"{len(rest) - len(seat)} replies to {len(sent)} frames, at most {most} "
                      f"were due: {[str(m)[:120] for m in rest]}; frames: "
                      + self._describe(sent))
        if sent and sent[-1].closes:
            if code not in (1008, 1009, 1007, None):
                s.problem(f"closed with {code_name(code)} after " + sent[-1].preview())
        elif not seat or code != 1008:
            s.problem(f"expected the seat refusal (an error seat_taken, then a close 1008), "
                      f"got close {code_name(code)} after "
                      f"{[(m.type, getattr(m, 'code', None)) if m else None for m in rest]}; "
                      + self._isolate_human(sent))

    def _isolate_human(self, frames: List[fuzz_frames.Frame]) -> str:
        """Each frame alone after our hello, on a connection of its own: which ones end in
        something else than the seat refusal."""
        found = []
        for frame in frames:
            try:
                ws = open_socket(self.port)
            except (WebSocketException, OSError):
                continue
            try:
                ws.send(hello_frame(self.token, self.port)[0])
                send_frame(ws, frame)
            except (WebSocketException, OSError):
                pass
            code, messages = wait_closed(ws, Stats(self.name, self.port), "isolating")
            hang_up(ws)
            if code != 1008:
                found.append(f"{frame.kind} ({frame.note}) {frame.preview()} -> close "
                             f"{code_name(code)}")
        return "frames that end otherwise, one by one: " + (" | ".join(found) or "none")


# -- checks on the whole stack ---------------------------------------------------------------

def still_up(name: str, port: int, token: str) -> str:
    """'' when the server at ``port`` takes an authenticated hello and proves the token in
    its answer (and answers a probe, or on the human port refuses the seat); else why not."""
    stats = Stats(name, port)
    try:
        ws = open_socket(port)
    except (WebSocketException, OSError) as exc:
        return f"{name} port {port}: cannot connect: {exc}"
    try:
        hello, nonce = hello_frame(token, port)
        ws.send(hello)
        msg = read_message(ws, ANSWER_TIMEOUT, stats, "hello")
        if not server_proves(msg, token, port, nonce):
            return f"{name} port {port}: the answer to our hello proves nothing: {msg}"
        if name == "human":
            try:
                ws.send(json.dumps({"type": PROBE_TYPE, "id": 1}))
            except ConnectionClosed as closed:
                # The server may refuse the seat (the MDP process holds it) before our probe
                # goes out: up, and refusing as it should (a CI run once saw it so).
                if closed.rcvd is not None and closed.rcvd.code == 1008 \
                        and "already served" in closed.rcvd.reason:
                    return ""
                raise
            code, messages = wait_closed(ws, stats, "refusal")
            if not any(isinstance(m, Error) and m.code == ERR_SEAT_TAKEN for m in messages) \
                    or code != 1008:
                return f"{name} port {port}: no seat refusal: {messages}, close {code}"
            return ""
        ws.send(json.dumps({"type": PROBE_TYPE, "id": 1}))
        msg = read_message(ws, ANSWER_TIMEOUT, stats, "probe")
        if not PortFuzzer._is_probe_answer(msg, 1):
            return f"{name} port {port}: the probe was answered with {msg}"
        return "; ".join(stats.problems)
    except Closed as closed:
        return f"{name} port {port}: closed ({code_name(closed.code)})"
    except (WebSocketException, TimeoutError) as exc:
        return f"{name} port {port}: {type(exc).__name__}: {exc}"
    finally:
        hang_up(ws)


def counts_block(fuzzers: List[PortFuzzer], seconds: float) -> str:
    head = (f"{'port':<12} {'frames':>7} {'unauth':>7} {'replies':>8} {'errors':>7} "
            f"{'conns':>6} {'closed':>7} {'survived':>9}  codes")
    lines = [f"==== fuzz of the two links: seed {SEED}, {seconds:.1f} s ====", head]
    total = Stats("total", 0)
    for f in fuzzers:
        s = f.stats
        lines.append(f"{s.name + ' ' + str(s.port):<12} {s.frames:>7} {s.unauth:>7} "
                     f"{s.replies:>8} {s.errors:>7} {s.conns:>6} {s.closed:>7} "
                     f"{s.survived:>9}  {dict(sorted(s.codes.items()))}")
        for key in ("frames", "unauth", "replies", "errors", "conns", "closed", "survived",
                    "bytes"):
            setattr(total, key, getattr(total, key) + getattr(s, key))
        total.codes.update(s.codes)
        total.reply_codes.update(s.reply_codes)
    lines.append(f"{'total':<12} {total.frames:>7} {total.unauth:>7} {total.replies:>8} "
                 f"{total.errors:>7} {total.conns:>6} {total.closed:>7} {total.survived:>9}  "
                 f"{dict(sorted(total.codes.items()))}")
    lines.append(f"error codes of the replies: {dict(total.reply_codes.most_common())}")
    lines.append(f"bytes of fuzz frames: {total.bytes}; frame kinds: "
                 + ", ".join(f"{k} {n}" for k, n in collections.Counter(
                     fr.kind for f in fuzzers for fr in f.frames).most_common()))
    lines.append("frames: fuzz frames sent; unauth: of which before/instead of a proving hello; "
                 "replies/errors: frames the server sent back to them / of which errors; "
                 "conns/closed: connections opened / closed by the server; survived: frames "
                 "after which the connection stayed open (the probe after them was answered); "
                 "codes: close codes (eof: no close frame)")
    return "\n".join(lines)


class TestFuzz(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_fuzz", anonymous=True)
        cls.log = StatusLog()
        cls.ports = {"pomdp": free_port(), "human": free_port()}
        cls.proc = start_stack("mode:=auto", "on_episode_end:=reset",
                               "step_delay:=0.1", "max_steps:=30",
                               f"pomdp_port:={cls.ports['pomdp']}",
                               f"human_port:={cls.ports['human']}", name="fuzz")
        try:
            cls.launch_log = os.readlink(f"/proc/{cls.proc.pid}/fd/1")
        except OSError:
            cls.launch_log = None

    @classmethod
    def tearDownClass(cls):
        stop_stack(cls.proc)

    def launch_output(self, offset: int = 0) -> str:
        if not self.launch_log:
            return ""
        try:
            with open(self.launch_log, "rb") as f:
                f.seek(offset)
                return f.read().decode("utf-8", "replace")
        except OSError:
            return ""

    def test_servers_survive_10000_fuzz_frames_and_the_loop_keeps_stepping(self):
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 3)
        self.assertTrue(ok, f"the loop is not stepping before the fuzz ({len(statuses)} steps)")
        self.assertIsNone(self.proc.poll(), "hrc.launch is not running")
        config = rospy.get_param("/hrc/config")
        token = read_token(config["token_file"])
        ports = {name: int(config[f"{name}_port"]) for name in PORT_NAMES}
        self.assertEqual(ports, self.ports)
        pids = {name: node_pids(self.proc, name) for name in PROCESSES}
        self.assertTrue(all(pids.values()), f"processes missing before the fuzz: {pids}")
        for name in PORT_NAMES:
            self.assertEqual(still_up(name, ports[name], token), "")

        generated = time.monotonic()
        fuzzers = []
        for k, name in enumerate(PORT_NAMES):
            frames = fuzz_frames.generate(f"{SEED}:{name}", FRAMES_PER_PORT,
                                          max_total_bytes=BYTES_PER_PORT)
            other = ports[PORT_NAMES[(k + 1) % len(PORT_NAMES)]]
            fuzzers.append(PortFuzzer(name, ports[name], token, frames, other, SEED * 10 + k))
        print(f"fuzz: {len(PORT_NAMES) * FRAMES_PER_PORT} frames generated in "
              f"{time.monotonic() - generated:.1f} s", flush=True)

        log_offset = len(self.launch_output().encode("utf-8"))
        started = time.monotonic()
        threads = [threading.Thread(target=f.run, name=f"fuzz-{f.name}") for f in fuzzers]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        seconds = time.monotonic() - started

        block = counts_block(fuzzers, seconds)
        print("\n" + block + "\n", flush=True)
        log_dir = os.environ.get("ROS_LOG_DIR")
        if log_dir:
            try:
                with open(os.path.join(log_dir, "fuzz_counts.txt"), "w") as f:
                    f.write(block + "\n")
            except OSError:
                pass

        # Still up: each server proves the token to a new client.
        self.log.clear()
        down = [why for why in (still_up(n, ports[n], token) for n in PORT_NAMES) if why]
        # Still stepping: new steps after the fuzz (the loop may have reset meanwhile).
        ok, statuses = self.log.wait_for(
            lambda s: sum(1 for x in s if not x.fault) >= STEPS_AFTER, STEPS_WAIT)
        after = {name: node_pids(self.proc, name) for name in PROCESSES}
        output = self.launch_output(log_offset)
        lines = output.splitlines()
        # One per failure: a chained exception's second traceback is not counted again.
        tracebacks = ["\n".join(lines[max(0, i - 3):i + 45]) for i, line in enumerate(lines)
                      if line.startswith("Traceback")
                      and not any("During handling" in x for x in lines[max(0, i - 2):i])]
        problems = [p for f in fuzzers for p in f.stats.problems]

        failures = []
        if problems:
            failures.append(f"{len(problems)} times the servers answered the fuzz otherwise "
                            "than the protocol says (the first 40):\n" + "\n".join(
                                p[:1500] for p in problems[:40]))
        if sum(f.stats.frames for f in fuzzers) < 10000:
            failures.append("fewer than 10,000 frames were sent")
        if down:
            failures.append("servers not up after the fuzz:\n" + "\n".join(down))
        if not ok:
            failures.append(f"the loop did not publish {STEPS_AFTER} fault-free steps within "
                            f"{STEPS_WAIT:g} s after the fuzz: "
                            f"{[(s.epoch, s.step, s.fault[:60]) for s in statuses][:20]}")
        if after != pids:
            failures.append(f"processes died or were respawned during the fuzz: before {pids}, "
                            f"after {after}")
        if self.proc.poll() is not None:
            failures.append("hrc.launch stopped")
        if tracebacks:
            failures.append(f"{len(tracebacks)} tracebacks in the launch's output during the "
                            f"fuzz ({self.launch_log}); the first:\n" + "\n----\n".join(
                                tracebacks[:3]))
        if failures:
            self.fail("\n\n".join([block] + failures))


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "hrc_fuzz", TestFuzz, sys.argv)
