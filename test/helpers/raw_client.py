"""A bare websocket connection for the link's tests, on websockets' threaded client: it sends
what MessageClient never would (frames before or instead of a hello, binary frames, frames
over the limit) and reads the server's frames one by one. Every wait is bounded by its
``timeout``, a safety net only."""
import socket
from typing import List, Optional, Tuple, Union

from websockets.exceptions import ConnectionClosed
from websockets.frames import CloseCode
from websockets.sync.client import connect


class RawConnection:
    """One connection to ``url``. It sends no keepalive ping and buffers at most one unread
    message, so a test that stops reading stops the socket being read too."""

    def __init__(self, url: str, timeout: float) -> None:
        self.timeout = timeout
        self.connection = connect(url, open_timeout=timeout, close_timeout=timeout,
                                  compression=None, max_size=None, max_queue=1,
                                  ping_interval=None, proxy=None, legacy=True)

    def send(self, data: Union[str, bytes]) -> None:
        """A text frame (``str``) or a binary one (``bytes``)."""
        self.connection.send(data)

    def recv(self) -> Union[str, bytes]:
        """The next message: ``str`` from a text frame, ``bytes`` from a binary one."""
        return self.connection.recv(timeout=self.timeout)

    def frames_until_closed(self) -> Tuple[List[str], Optional[int]]:
        """Every message the server sends until it closes, then its close code (``None``: the
        connection ended without a close frame or with one without a code, or it did not end
        within the timeout)."""
        got = []
        try:
            while True:
                got.append(self.recv())
        except ConnectionClosed as closed:
            code = closed.rcvd.code if closed.rcvd is not None else None
            return got, None if code == CloseCode.NO_STATUS_RCVD else code
        except TimeoutError:   # it never closed
            return got, None
        finally:
            self.vanish()

    def close(self) -> None:
        """Close properly (code 1000)."""
        self.connection.close()

    def vanish(self) -> None:
        """End the connection without a close frame, as when the process is killed."""
        try:
            self.connection.socket.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.connection.close()
