"""The viewer's browser host without a browser (issue 23): the command, its page and socket, Ctrl-C.

The WebSocket is spoken here with aiohttp's client exactly as static/index.html speaks it.
"""

from __future__ import annotations

import asyncio
import json
import os
import queue
import signal
import struct
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request

import pytest

pytest.importorskip("aiohttp", reason="the viewer's server needs the 'view' extra (aiohttp)")

from warp_spt.viewer.server import ViewerServer, pack   # noqa: E402
from warp_spt.viewer.session import open_session        # noqa: E402

from tests.support.scenes import box_obj, write_scene_files           # noqa: E402

TIMEOUT = 600


def unpack(data: bytes) -> tuple[dict, list[bytes]]:
    """A binary frame as index.html decodes it."""
    (length,) = struct.unpack_from("<I", data, 0)
    header = json.loads(data[4:4 + length])
    out, offset = [], 4 + length
    for n in header["buffers"]:
        out.append(data[offset:offset + n])
        offset += n
    return header["message"], out


def test_pack_round_trips():
    message, buffers = unpack(pack({"type": "frame", "spp": 3}, [b"abc", b"", b"\x00" * 5]))
    assert message == {"type": "frame", "spp": 3} and buffers == [b"abc", b"", b"\x00" * 5]


async def talk(url: str, until, send=({"type": "hello"},), timeout: float = TIMEOUT) -> list:
    """Open the page's socket, send messages, collect (message, buffers) until ``until(list)``."""
    import aiohttp

    got: list = []
    async with aiohttp.ClientSession() as http:
        async with http.ws_connect(url.replace("http", "ws") + "ws", origin=url.rstrip("/")) as ws:
            for message in send:
                await ws.send_str(json.dumps(message))
            deadline = time.monotonic() + timeout
            while not until(got):
                raw = await ws.receive(timeout=max(0.1, deadline - time.monotonic()))
                if raw.type == aiohttp.WSMsgType.TEXT:
                    got.append((json.loads(raw.data), []))
                elif raw.type == aiohttp.WSMsgType.BINARY:
                    got.append(unpack(raw.data))
                else:
                    raise AssertionError(f"socket closed: {raw}")
    return got


def frames(got: list) -> list:
    return [(m, b) for m, b in got if m["type"] == "frame"]


def read_line(stream, timeout: float) -> str:
    """The next line of a child's output, or '' after ``timeout`` seconds."""
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=lambda: lines.put(stream.readline()), daemon=True).start()
    try:
        return lines.get(timeout=timeout)
    except queue.Empty:
        return ""


def get(url: str, host: str | None = None) -> tuple[int, str, bytes]:
    request = urllib.request.Request(url, headers={"Host": host} if host else {})
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status, response.headers.get("Content-Type", ""), response.read()
    except urllib.error.HTTPError as err:
        return err.code, "", b""


def test_the_command_serves_the_page_and_stops_on_ctrl_c():
    proc = subprocess.Popen([sys.executable, "-m", "warp_spt", "view", "--no-browser", "-res", "32", "24"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ.copy())
    try:
        line = read_line(proc.stdout, TIMEOUT)
        assert line.startswith("warp-spt view: serving http://127.0.0.1:"), (line, proc.poll())
        url = line.split()[3]
        status, kind, body = get(url)
        assert status == 200 and kind.startswith("text/html") and b"./viewer.js" in body
        status, kind, body = get(url + "viewer.js")
        assert status == 200 and "javascript" in kind and b"export default" in body
        assert get(url, host="attacker.example:80")[0] == 403             # DNS rebinding
        got = asyncio.run(talk(url, lambda got: any(m.get("mode") == "refine" for m, _ in frames(got))))
        state = next(m for m, _ in got if m["type"] == "state")
        assert state["settings"]["width"] == 32 and "nee" in state["integrators"]
        message, buffers = frames(got)[-1]
        assert message["view"] == [32, 24] and buffers[0][:2] == b"\xff\xd8"
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert err == "warp-spt view: interrupted\n"


@pytest.mark.parametrize("argv, message", [(["-mtl", "x.mtl"], "without any -obj"),
                                           (["--port", "70000"], "--port"),
                                           (["-cam", "0", "0", "0", "0", "0", "0", "38", "1", "0"], "-cam"),
                                           (["--bogus"], "unrecognized")])
def test_bad_arguments_exit_2(argv, message):
    proc = subprocess.run([sys.executable, "-m", "warp_spt", "view", "--no-browser", *argv], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2 and message in proc.stderr and "Traceback" not in proc.stderr


@pytest.fixture
def bad_scene_server(tmp_path):
    objs, mtls = write_scene_files(tmp_path, "room", box_obj(material="wall"), "newmtl wall\nKd 0.5 oops 0.5\n")
    session = open_session(objs=objs, mtls=mtls, width=16, height=12)
    server = ViewerServer(session)
    url = server.start_thread()
    yield url, session
    server.stop_thread()
    session.close()


def test_a_scene_error_reaches_the_page(bad_scene_server):
    url, _ = bad_scene_server
    got = asyncio.run(talk(url, lambda got: any(m["type"] == "state" and m["error"] for m, _ in got)))
    error = next(m["error"] for m, _ in got if m["type"] == "state" and m["error"])
    assert "room.mtl:2" in error and "oops" in error


def test_a_bad_message_gets_a_notice_and_the_socket_stays(bad_scene_server):
    url, _ = bad_scene_server
    sent = ({"type": "hello"}, {"type": "set", "key": "max_depth", "value": -1}, {"type": "hello"})
    def answered(got) -> bool:         # the notice, and the second hello's state after it
        kinds = [m["type"] for m, _ in got]
        return "notice" in kinds and "state" in kinds[kinds.index("notice"):]

    got = asyncio.run(talk(url, answered, send=sent))
    assert any(m["type"] == "notice" and "max_depth" in m["text"] for m, _ in got)


def test_a_second_tab_is_told_it_shares_the_first_tabs_session(bad_scene_server):
    """Two pages of one server show one session (one render for the machine): the second is told on
    its hello, the first is told a tab joined, and both states count two views; when one leaves,
    the other's state counts one. Settings one tab sets reach the other."""
    import aiohttp

    url, session = bad_scene_server

    async def receive_until(ws, until, got):
        deadline = time.monotonic() + TIMEOUT
        while not until(got):
            raw = await ws.receive(timeout=max(0.1, deadline - time.monotonic()))
            assert raw.type in (aiohttp.WSMsgType.TEXT, aiohttp.WSMsgType.BINARY), raw
            got.append(json.loads(raw.data) if raw.type == aiohttp.WSMsgType.TEXT else unpack(raw.data)[0])
        return got

    def notices(got):
        return [m["text"] for m in got if m["type"] == "notice"]

    def counts(got):
        return [m["viewers"] for m in got if m["type"] == "state"]

    async def two_tabs():
        first_got, second_got = [], []
        async with aiohttp.ClientSession() as http:
            ws_url, origin = url.replace("http", "ws") + "ws", url.rstrip("/")
            async with http.ws_connect(ws_url, origin=origin) as first:
                await first.send_str(json.dumps({"type": "hello"}))
                await receive_until(first, lambda g: 1 in counts(g), first_got)
                async with http.ws_connect(ws_url, origin=origin) as second:
                    await second.send_str(json.dumps({"type": "hello"}))
                    await receive_until(second, lambda g: notices(g) and counts(g), second_got)
                    await receive_until(first, lambda g: notices(g) and 2 in counts(g), first_got)
                    await second.send_str(json.dumps({"type": "set", "key": "max_depth", "value": 3}))
                    await receive_until(first, lambda g: any(m["type"] == "state" and m["settings"]["max_depth"] == 3
                                                             for m in g), first_got)
                await receive_until(first, lambda g: counts(g)[-1] == 1, first_got)
        return first_got, second_got

    first_got, second_got = asyncio.run(two_tabs())
    assert counts(second_got)[0] == 2
    assert "open in 1 other tab" in notices(second_got)[0] and "a change here changes it there" in notices(second_got)[0]
    assert counts(first_got)[0] == 1 and notices(first_got)[0].startswith("another tab opened this view (2 in all)")
