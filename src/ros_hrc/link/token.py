"""The per-launch link secret (DESIGN §12): who may speak on the three websocket links.

``hrc.launch`` has its pre-flight (``hrc_check --link-session NAME``) make a fresh random
token before any process starts, in a file only this user can read::

    $ROS_HOME/ros_hrc/links/<NAME>.token      (ROS_HOME defaults to ~/.ros; directory 0700,
                                                file 0600, written once, never overwritten)

Every process of the launch is given the session ``NAME`` (``$(anon hrc_link)``, not secret)
and reads the token from that file, so the secret is never on a command line, in the
environment or on the parameter server, where other processes could read it. A process run by
hand is given the file instead: ``--token-file PATH`` or the environment variable
:data:`TOKEN_FILE_ENV`; ``hrc.launch`` prints the path when a solver is left to be run by hand.

The token itself never crosses the wire either. A client's ``hello`` carries a fresh
``nonce`` and ``auth`` = HMAC-SHA256(token, "ros_hrc link|client|<port>|<who>|<nonce>"); the
server checks it (and refuses a nonce it has already accepted), then answers with a hello
whose ``auth`` is the same HMAC over "server" instead of "client". So a process that took a
link's port before the stack started learns nothing it could use on another port, and a
client never takes a server that cannot prove it knows the token for its own.

Beside the token, the pre-flight writes the launch's resolved settings (every launch argument
checked, defaults filled in, paths made absolute against the directory roslaunch was started
from)::

    $ROS_HOME/ros_hrc/links/<NAME>.settings.json   (file 0600, written once)

A solver process given ``--link-session NAME`` takes its options from there
(:func:`read_session_settings`), so that no path the user typed reaches it unresolved, and
nothing a user typed is split by the launch file's command lines. It goes when the token goes.

No ROS, no sockets: :mod:`ros_hrc.link.transport` uses these functions on both ends.
"""
from __future__ import annotations

import errno
import hashlib
import hmac
import json
import os
import re
import secrets
import stat
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Tuple

from ros_hrc.errors import LinkError
from ros_hrc.model_files import ros_home
from ros_hrc.process_tree import alive, parent_of

#: The environment variable naming a token file, for a process run by hand.
TOKEN_FILE_ENV = "HRC_LINK_TOKEN_FILE"
#: A token: 32 random bytes, written as 64 lowercase hex digits.
TOKEN_BYTES = 32
#: A hello's nonce: 16 random bytes as 32 hex digits (a repeat is refused).
NONCE_BYTES = 16
#: An ``auth`` field: HMAC-SHA256, 64 hex digits.
AUTH_HEX_CHARS = 64
_TOKEN_SUFFIX = ".token"
_SETTINGS_SUFFIX = ".settings.json"
_SESSION_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,199}")
_HEX = re.compile(r"[0-9a-f]+")
# The text every proof is taken over: the role, the server's port, the sender's name, the
# client's nonce. Changing it is a protocol change.
_PROOF_FORMAT = "ros_hrc link|{role}|{port}|{who}|{nonce}"


class TokenError(LinkError):
    """The link token cannot be made, found or read; one line saying which file and why."""


def token_dir(environ: Optional[Mapping[str, str]] = None) -> Path:
    """Where launches keep their tokens: ``$ROS_HOME/ros_hrc/links`` (:func:`ros_home`)."""
    return ros_home(environ) / "ros_hrc" / "links"


def session_token_file(session: str, environ: Optional[Mapping[str, str]] = None) -> Path:
    """The token file of launch session ``session`` (a name such as ``$(anon hrc_link)``)."""
    if not isinstance(session, str) or not _SESSION_PATTERN.fullmatch(session):
        raise TokenError(f"link session {session!r}: must be 1 to 200 letters, digits, '_', "
                         "'.' or '-', starting with a letter or digit")
    return token_dir(environ) / (session + _TOKEN_SUFFIX)


def session_settings_file(session: str, environ: Optional[Mapping[str, str]] = None) -> Path:
    """The resolved settings of launch session ``session``, beside its token file."""
    token = session_token_file(session, environ)
    return token.with_name(token.name[:-len(_TOKEN_SUFFIX)] + _SETTINGS_SUFFIX)


def _write_private_file(path: Path, text: str, existing: str, what: str) -> None:
    """Create ``path`` exclusively (never overwritten, never through a symbolic link), mode
    0600, holding ``text``; a write that fails (a full disk) leaves no half-written file.
    Raises :class:`TokenError` naming ``existing`` (it exists) or ``what`` (cannot write)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags, 0o600)
    except FileExistsError:
        raise TokenError(f"{path}: {existing} exists already; a session name is used by one "
                         "launch only") from None
    except OSError as exc:
        raise TokenError(f"{path}: cannot write {what}: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as exc:
        remove_token(path)
        raise TokenError(f"{path}: cannot write {what}: {exc.strerror or exc}") from None


def write_session_settings(session: str, config: Mapping[str, Any],
                           environ: Optional[Mapping[str, str]] = None) -> Path:
    """Write the launch's resolved settings (JSON values: text, numbers, booleans, null) for
    its processes; created exclusively with mode 0600 like the token. Its path; raises
    :class:`TokenError`."""
    path = session_settings_file(session, environ)
    _private_dir(path.parent)
    text = json.dumps(dict(config), ensure_ascii=False, indent=1) + "\n"
    _write_private_file(path, text, "the settings of this session", "the launch's settings")
    return path


def replace_session_settings(session: str, config: Mapping[str, Any],
                             environ: Optional[Mapping[str, str]] = None) -> Path:
    """Replace the resolved settings of a running launch session (a warm stack's next cell:
    its processes read them again on ``configure``): written beside, mode 0600, then
    renamed over the old file, so that a reader sees the old settings or the new, whole.
    Only a session whose settings exist is rewritten. Its path; raises :class:`TokenError`."""
    path = session_settings_file(session, environ)
    if not path.is_file():
        raise TokenError(f"{path}: no settings for link session {session} to replace")
    beside = path.with_name(f".{path.name}.{os.getpid()}.new")
    text = json.dumps(dict(config), ensure_ascii=False, indent=1) + "\n"
    remove_token(beside)     # a leftover of a process of this pid that died mid-write
    _write_private_file(beside, text, "a settings file being written", "the launch's settings")
    try:
        os.replace(beside, path)
    except OSError as exc:
        remove_token(beside)
        raise TokenError(f"{path}: cannot replace the launch's settings: "
                         f"{exc.strerror or exc}") from None
    return path


def read_session_settings(session: str, environ: Optional[Mapping[str, str]] = None
                          ) -> Dict[str, Any]:
    """The resolved settings the pre-flight of launch session ``session`` wrote (setting name
    -> value); :class:`TokenError` with one line when there are none or they are unreadable."""
    path = session_settings_file(session, environ)
    try:
        with open(path, encoding="utf-8") as f:
            config = json.load(f)
    except FileNotFoundError:
        raise TokenError(f"{path}: no settings for link session {session} (hrc.launch's "
                         "pre-flight, hrc_check --link-session, writes them)") from None
    except (OSError, ValueError) as exc:
        raise TokenError(f"{path}: cannot read the launch's settings: "
                         f"{getattr(exc, 'strerror', None) or exc}") from None
    if not isinstance(config, dict):
        raise TokenError(f"{path}: not a launch's settings (expected a JSON object)")
    return config


def _private_dir(path: Path) -> None:
    """Make ``path`` (and its parents) if needed; refuse it unless only we can use it."""
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = path.lstat()
    except OSError as exc:
        raise TokenError(f"{path}: cannot make the token directory: {exc.strerror or exc}") \
            from None
    if not stat.S_ISDIR(info.st_mode):
        raise TokenError(f"{path}: is not a directory")
    if info.st_uid != os.geteuid():
        raise TokenError(f"{path}: belongs to another user; tokens must live in a directory "
                         "of your own")
    if info.st_mode & 0o077:
        try:
            os.chmod(path, 0o700)
        except OSError as exc:
            raise TokenError(f"{path}: others may read it and it cannot be made private: "
                             f"{exc.strerror or exc}") from None


def mint_token(session: str, launcher_pid: Optional[int] = None,
               environ: Optional[Mapping[str, str]] = None) -> Path:
    """Make the token of a new launch session and return its file. The file is created
    exclusively (never overwritten, never through a symbolic link) with mode 0600; its second
    line names the launching process, so :func:`prune_tokens` can remove it once that process
    is gone. Raises :class:`TokenError`."""
    path = session_token_file(session, environ)
    _private_dir(path.parent)
    text = secrets.token_hex(TOKEN_BYTES) + "\n"
    if launcher_pid is not None:
        text += f"launcher {int(launcher_pid)}\n"
    _write_private_file(path, text, "a token of this session", "the token")
    return path


def read_token(path: os.PathLike) -> str:
    """The token in ``path``; refuses (:class:`TokenError`) a missing file, a symbolic link,
    one that others may read or that belongs to another user, and malformed contents."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except FileNotFoundError:
        raise TokenError(f"{path}: no such link token file (is the launch running? "
                         "hrc.launch makes it at start-up)") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise TokenError(f"{path}: is a symbolic link; give the token file itself") \
                from None
        raise TokenError(f"{path}: cannot read the link token: {exc.strerror or exc}") \
            from None
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(f.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise TokenError(f"{path}: is not a regular file")
        if info.st_uid != os.geteuid():
            raise TokenError(f"{path}: belongs to another user")
        if info.st_mode & 0o077:
            raise TokenError(f"{path}: others may read it (mode {info.st_mode & 0o777:o}); "
                             "a token file must be private (chmod 600)")
        data = f.read(1024)
    first = data.split(b"\n", 1)[0].strip()
    token = first.decode("ascii", "replace")
    if len(token) != 2 * TOKEN_BYTES or not _HEX.fullmatch(token):
        raise TokenError(f"{path}:1: not a link token (expected {2 * TOKEN_BYTES} lowercase "
                         "hex digits)")
    return token


def resolve_token(session: Optional[str] = None, token_file: Optional[str] = None,
                  environ: Optional[Mapping[str, str]] = None) -> Tuple[str, Path]:
    """(token, its file) for a process: ``token_file`` if given, else the file of launch
    session ``session``, else the file named by :data:`TOKEN_FILE_ENV`. Raises
    :class:`TokenError` when none is given or the file cannot be read."""
    environ = os.environ if environ is None else environ
    if token_file:
        path = Path(os.path.expanduser(token_file))
    elif session:
        path = session_token_file(session, environ)
    elif environ.get(TOKEN_FILE_ENV):
        path = Path(os.path.expanduser(environ[TOKEN_FILE_ENV]))
    else:
        raise TokenError("no link token: the links take only processes of the same launch. "
                         f"Give --token-file PATH or set {TOKEN_FILE_ENV}=PATH (hrc.launch "
                         "prints the path when a solver is to be run by hand)")
    return read_token(path), path


def remove_token(path: os.PathLike) -> bool:
    """Delete a token file; whether it was there."""
    try:
        os.unlink(path)
        return True
    except FileNotFoundError:
        return False


def launcher_of(path: os.PathLike) -> Optional[int]:
    """The pid of the process that launched the session of token file ``path`` (its second
    line, ``launcher PID``: :func:`mint_token`), or None when the file cannot be read or
    names none."""
    try:
        with open(path, "rb") as f:
            lines = f.read(1024).split(b"\n")
    except OSError:
        return None
    words = lines[1].split() if len(lines) > 1 else []
    if len(words) == 2 and words[0] == b"launcher" and words[1].isdigit():
        return int(words[1])
    return None


def prune_tokens(environ: Optional[Mapping[str, str]] = None) -> int:
    """Remove the token files whose launching process has ended (a launch that stopped,
    however it stopped); how many. Files without a launcher line are left alone."""
    directory = token_dir(environ)
    removed = 0
    try:
        entries = list(directory.glob("*" + _TOKEN_SUFFIX))
    except OSError:
        return 0
    for path in entries:
        launcher = launcher_of(path)
        # A launcher that is a zombie has ended too (it only waits to be reaped).
        if launcher is not None and not alive(launcher):
            removed += remove_token(path)
            remove_token(path.with_name(path.name[:-len(_TOKEN_SUFFIX)] + _SETTINGS_SUFFIX))
    return removed


def stop_launch(session: str, environ: Optional[Mapping[str, str]] = None) -> Optional[int]:
    """Stop the launch of ``session`` as Ctrl-C would (SIGINT to its launcher, the roslaunch
    named in the token file), for a process of it that cannot start on the launch's settings:
    respawned, it would only fail again, about once a second, and nothing would step. Only a
    launcher that is this process's ancestor is signalled. Its pid, or None if none was."""
    import signal

    try:
        launcher = launcher_of(session_token_file(session, environ))
    except TokenError:      # not a session's name
        return None
    if launcher is None:
        return None
    pid: Optional[int] = os.getpid()
    for _ in range(8):          # roslaunch, or an xterm (launch-prefix) under it
        pid = parent_of(pid) if pid else None
        if pid is None or pid <= 1:
            return None
        if pid == launcher:
            os.kill(launcher, signal.SIGINT)
            return launcher
    return None


def new_nonce() -> str:
    """A fresh hello nonce."""
    return secrets.token_hex(NONCE_BYTES)


def proof(token: str, role: str, port: int, who: str, nonce: str) -> str:
    """The ``auth`` of a hello: HMAC-SHA256 keyed with the token over the role (``client`` or
    ``server``), the server's port, the sender's ``who`` and the client's nonce."""
    text = _PROOF_FORMAT.format(role=role, port=int(port), who=who, nonce=nonce)
    return hmac.new(token.encode("ascii"), text.encode("utf-8"), hashlib.sha256).hexdigest()


def proof_matches(token: str, given: Optional[str], role: str, port: int, who: str,
                  nonce: Optional[str]) -> bool:
    """Whether ``given`` is the right ``auth`` (compared in constant time)."""
    if not isinstance(given, str) or not isinstance(nonce, str):
        return False
    return hmac.compare_digest(proof(token, role, port, who, nonce), given)


def add_token_arguments(parser) -> None:
    """``--link-session`` (given by hrc.launch) and ``--token-file`` (by hand) on an argparse
    parser of a solver process."""
    parser.add_argument("--link-session", default="", metavar="NAME",
                        help="the launch session whose link token to use (hrc.launch gives it)")
    parser.add_argument("--token-file", default="", metavar="PATH",
                        help=f"the link token's file, for a process run by hand (hrc.launch "
                             f"prints it; or set {TOKEN_FILE_ENV})")


def launch_token(source) -> str:
    """The token ``source`` names: its ``link_session`` and ``token_file`` (the options of
    :func:`add_token_arguments`, or a node's config fields of those names), else the
    environment; raises :class:`TokenError` with one line when there is none."""
    token, _path = resolve_token(session=source.link_session or None,
                                 token_file=source.token_file or None)
    return token
