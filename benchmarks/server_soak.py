"""A soak of ``pliant view``'s server, on 127.0.0.1 only, bounded in count and time.

    .venv/bin/python benchmarks/server_soak.py [--tabs 20] [--sessions 4]

Against a live server on the bundled engine bay (each tab its own solver process):

1. ``--tabs`` tabs, one after another, each opening its session, moving the hand (so a
   solve is running) and vanishing without a goodbye (the socket closed mid-solve): the
   solver processes alive 1 s and 5 s after the last, and the server's memory.
2. ``--sessions`` tabs at once, and one more (told the server is busy).
3. A worker killed under a tab (the OOM killer, say): the tab's next answer comes from
   a new one.
4. A tab that sends and never reads: dropped after the send timeout, its worker freed.
5. Stopping the server with all that behind it.

Prints each figure; exits 1 if a solver process outlives its tab by 5 s, the bound is not
held, or a killed worker is not replaced.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "examples" / "scenes" / "engine_bay.toml"
sys.path.insert(0, str(ROOT / "tests"))


def workers() -> list:
    import psutil

    return [p for p in psutil.Process().children(recursive=True)
            if "pliant.session.worker" in " ".join(p.cmdline())]


def rss_mb() -> float:
    import psutil

    return psutil.Process().memory_info().rss / 2 ** 20


def receive(ws, kind: str, timeout: float = 120.0) -> dict:
    while True:
        message = json.loads(ws.recv(timeout=timeout))
        if message["type"] in (kind, "error"):
            return message


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tabs", type=int, default=20)
    parser.add_argument("--sessions", type=int, default=4)
    args = parser.parse_args()
    from contextlib import ExitStack

    from websockets.sync.client import connect as ws_connect

    from pliant.viewer.server import Server

    stack = ExitStack()

    def connect(url: str, **options):
        return stack.enter_context(ws_connect(url, **options))

    failed = False
    hello = json.dumps({"v": 1, "type": "hello"})
    server = Server(SCENE, port=0, live=True, sessions=args.sessions).start()
    url = f"ws://127.0.0.1:{server.port}/ws"
    start_rss = rss_mb()

    def move(ws, k: int) -> None:
        ws.send(json.dumps({"v": 1, "type": "move", "grip": "hand", "seq": k,
                            "position": [0.05 + 0.002 * k, 0.02, 0.42],
                            "tangent": [0.0, 0.0, -1.0]}))

    # 1. tabs that vanish mid-solve
    started = time.perf_counter()
    rss = []
    for k in range(args.tabs):
        if k in (2, args.tabs // 2, args.tabs - 1):
            rss.append(rss_mb())
        ws = connect(url, open_timeout=120)
        ws.send(hello)
        receive(ws, "frame")
        move(ws, 1)
        ws.socket.shutdown(socket.SHUT_RDWR)  # gone, no closing handshake
        ws.socket.close()
    last = time.perf_counter()
    time.sleep(1.0)
    after_1 = len(workers())
    time.sleep(4.0)
    after_5 = len(workers())
    print(f"{args.tabs} tabs closed mid-solve in {last - started:.1f} s: solver processes "
          f"alive 1 s after the last {after_1}, 5 s after {after_5}; server memory "
          f"{start_rss:.0f} MB at the start, {rss[0]:.0f} MB after 2 tabs, {rss[1]:.0f} MB "
          f"after {args.tabs // 2}, {rss[2]:.0f} MB after {args.tabs - 1}")
    failed |= after_5 > 0

    # 2. the bound
    tabs = [connect(url, open_timeout=120) for _ in range(args.sessions)]
    for ws in tabs:
        ws.send(hello)
        receive(ws, "frame")
    extra = connect(url, open_timeout=120)
    busy = json.loads(extra.recv(timeout=60))
    extra.close()
    print(f"{args.sessions} tabs at once: {len(workers())} solver processes, server memory "
          f"{rss_mb():.0f} MB; one more: {busy['message'][:60]}…")
    failed |= busy["type"] != "error" or len(workers()) > args.sessions

    # 3. a worker killed under a tab
    victim = workers()[0]
    victim.kill()
    answers = 0
    for ws in tabs:
        move(ws, 2)
        answer = receive(ws, "accurate")
        answers += bool(answer.get("ok"))
    print(f"a worker killed: {answers} of {len(tabs)} tabs answered after it "
          f"({len(workers())} solver processes)")
    failed |= answers != len(tabs)
    for ws in tabs:
        ws.close()

    deadline = time.perf_counter() + 60
    while server.open_sessions and time.perf_counter() < deadline:
        time.sleep(0.05)  # the closed tabs' sessions freed

    # 4. a tab that never reads
    from test_viewer import _raw_websocket

    from pliant.viewer import server as server_module

    server_module.SEND_TIMEOUT = 2.0
    sock, send = _raw_websocket(server.port)
    sock.settimeout(2.0)
    t0 = time.perf_counter()
    try:
        send(hello)
        for k in range(20_000):
            send(json.dumps({"v": 1, "type": "move", "grip": "hand", "seq": k + 1,
                             "position": [0.05 + 1e-5 * (k % 100), 0.02, 0.42],
                             "tangent": [0.0, 0.0, -1.0]}))
    except OSError:
        pass
    while server.dropped == 0 and time.perf_counter() - t0 < 120:
        time.sleep(0.1)
    print(f"a tab that never reads: dropped after {time.perf_counter() - t0:.1f} s "
          f"(send timeout {server_module.SEND_TIMEOUT:g} s)")
    sock.close()
    failed |= server.dropped != 1

    # 5. stopping
    stack.close()
    t0 = time.perf_counter()
    server.stop()
    time.sleep(0.5)
    print(f"stopped in {time.perf_counter() - t0:.1f} s; solver processes left: "
          f"{len(workers())}")
    failed |= bool(workers())
    return 1 if failed else 0


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.default_int_handler)
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    sys.exit(main())
