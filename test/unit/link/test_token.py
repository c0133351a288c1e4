"""The per-launch link token (ros_hrc.link.token): made private, read only when private, found
by session, by file or by environment; hello proofs. (Pruned once its launch has ended:
test/integration/link/test_link_processes.py.)"""
import os

import pytest

from ros_hrc.link.token import (TOKEN_FILE_ENV, TokenError, mint_token, proof, proof_matches,
                                read_token, resolve_token, session_token_file,
                                token_dir)


@pytest.fixture
def home(tmp_path):
    return {"ROS_HOME": str(tmp_path / "ros_home")}


def test_a_minted_token_is_private_random_and_found_by_its_session(home):
    path = mint_token("hrc_link_a", launcher_pid=os.getpid(), environ=home)
    assert path == session_token_file("hrc_link_a", home) == token_dir(home) / "hrc_link_a.token"
    assert oct(path.stat().st_mode & 0o777) == "0o600"
    assert oct(path.parent.stat().st_mode & 0o777) == "0o700"
    token = read_token(path)
    assert len(token) == 64 and int(token, 16) >= 0
    assert resolve_token(session="hrc_link_a", environ=home) == (token, path)
    other = read_token(mint_token("hrc_link_b", environ=home))
    assert other != token


def test_a_session_token_is_never_overwritten(home):
    mint_token("once", environ=home)
    with pytest.raises(TokenError, match="exists already"):
        mint_token("once", environ=home)


@pytest.mark.parametrize("session", ["", "../x", "a/b", "-x", "a b", "x" * 201, "é"])
def test_a_session_name_cannot_leave_the_token_directory(session, home):
    with pytest.raises(TokenError, match="link session"):
        session_token_file(session, home)


def test_a_token_file_others_may_read_is_refused(home):
    path = mint_token("open", environ=home)
    os.chmod(path, 0o644)
    with pytest.raises(TokenError, match=r"others may read it \(mode 644\).*chmod 600"):
        read_token(path)


def test_a_symbolic_link_and_a_missing_or_malformed_file_are_refused(home, tmp_path):
    path = mint_token("real", environ=home)
    link = tmp_path / "link.token"
    link.symlink_to(path)
    with pytest.raises(TokenError, match="symbolic link"):
        read_token(link)
    with pytest.raises(TokenError, match="no such link token file"):
        read_token(tmp_path / "none.token")
    bad = tmp_path / "bad.token"
    bad.write_text("not a token\n")
    os.chmod(bad, 0o600)
    with pytest.raises(TokenError, match=r"bad.token:1: not a link token"):
        read_token(bad)


def test_the_token_file_comes_from_the_option_then_the_session_then_the_environment(home):
    by_session = mint_token("s1", environ=home)
    by_env = mint_token("s2", environ=home)
    given = mint_token("s3", environ=home)
    env = dict(home, **{TOKEN_FILE_ENV: str(by_env)})
    assert resolve_token(session="s1", token_file=str(given), environ=env)[1] == given
    assert resolve_token(session="s1", environ=env)[1] == by_session
    assert resolve_token(environ=env)[1] == by_env
    with pytest.raises(TokenError, match="no link token.*--token-file PATH.*HRC_LINK_TOKEN_FILE"):
        resolve_token(environ=home)


def test_a_proof_binds_the_token_role_port_name_and_nonce():
    token, nonce = "ab" * 32, "cd" * 16
    given = proof(token, "client", 7070, "hrc_obs", nonce)
    assert len(given) == 64
    assert proof_matches(token, given, "client", 7070, "hrc_obs", nonce)
    for change in (dict(token="ef" * 32), dict(role="server"), dict(port=8080),
                   dict(who="intruder"), dict(nonce="00" * 16)):
        args = dict(token=token, role="client", port=7070, who="hrc_obs", nonce=nonce, **{})
        args.update(change)
        assert not proof_matches(args["token"], given, args["role"], args["port"], args["who"],
                                 args["nonce"])
    assert not proof_matches(token, None, "client", 7070, "hrc_obs", nonce)
