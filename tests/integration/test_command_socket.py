"""The command socket: frames of bounded size, one live service per name, and who may be at either end."""

from __future__ import annotations

import os
import struct
import uuid

import pytest

from plem.ipc.command_socket import (
    CommandSocketError,
    FrameReader,
    connect,
    frame,
    listen,
    peer_credentials,
    remove_own_socket,
    socket_path,
)
from tests.e2e.launched import as_nobody, read_line, system_python


@pytest.fixture
def robot_id():
    name = f"sock_{uuid.uuid4().hex[:8]}"
    yield name
    socket_path(name).unlink(missing_ok=True)


def test_frames_arrive_whole_however_the_bytes_are_split():
    reader = FrameReader(limit=100)
    stream = frame(b"first") + frame(b"") + frame(b"x" * 100)
    received = [record for i in range(len(stream)) for record in reader.feed(stream[i:i + 1])]
    assert received == [b"first", b"", b"x" * 100]


def test_a_frame_announcing_more_than_the_limit_is_refused_before_it_is_read():
    reader = FrameReader(limit=100)
    with pytest.raises(CommandSocketError, match="too large"):
        reader.feed(struct.pack("<I", 101))


def test_one_live_service_per_robot_and_a_stale_socket_is_replaced(robot_id):
    server = listen(robot_id)
    try:
        assert oct(socket_path(robot_id).stat().st_mode & 0o777) == "0o600"
        with pytest.raises(CommandSocketError, match="already has a command service"):
            listen(robot_id)
        client = connect(robot_id)
        client.close()
    finally:
        server.close()
    listen(robot_id).close()    # the name is left behind by a service that is gone: taken over


def test_a_file_that_is_not_a_socket_is_never_taken_over(robot_id):
    socket_path(robot_id).write_text("not a socket")
    with pytest.raises(CommandSocketError, match="is taken"):
        listen(robot_id)
    assert socket_path(robot_id).read_text() == "not a socket"
    with pytest.raises(CommandSocketError, match="cannot reach the command service"):
        connect(robot_id)


@pytest.mark.skipif(os.geteuid() != 0 or system_python() is None,
                    reason="acting as another user needs root and a system Python of the tests' version")
def test_a_service_run_by_another_user_is_never_commanded(robot_id):
    squatter = as_nobody("""
        import os, socket, sys, time
        from plem.ipc.command_socket import listen
        server = listen(sys.argv[1])
        os.chmod(f"/dev/shm/{sys.argv[1]}_commands", 0o666)   # open to everyone: the client must still refuse
        print("listening", flush=True)
        time.sleep(60)
    """, robot_id)
    try:
        assert read_line(squatter, 30) == "listening\n", squatter.stderr.read() if squatter.poll() else ""
        with pytest.raises(CommandSocketError, match="served by another user's process") as caught:
            connect(robot_id)
        assert "nobody (uid 65534)" in caught.value.why
        with pytest.raises(CommandSocketError, match="is taken"):
            listen(robot_id)
        remove_own_socket(robot_id)
        assert socket_path(robot_id).exists()   # another user's socket is left for them (or root, by hand)
    finally:
        squatter.kill()
        squatter.wait(10)


def test_the_service_end_sees_who_connected(robot_id):
    server = listen(robot_id)
    try:
        client = connect(robot_id)
        accepted, _ = server.accept()
        pid, uid, _ = peer_credentials(accepted)
        assert (pid, uid) == (os.getpid(), os.geteuid())
        accepted.close()
        client.close()
    finally:
        server.close()
