"""The wheel runs everything on its own: built from this checkout, installed in a fresh
virtual environment outside it (no repository, no npm, no Node on the path; the
dependencies this environment's), it prints its version, runs the main job on its
bundled scene and serves the page with the libraries it carries. About a minute: the
fresh install's one compile of the solvers."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import sysconfig
import time
import urllib.request
from pathlib import Path

import pytest

from pliant.models import first_run

ROOT = Path(__file__).resolve().parents[1]
NODE_MODULES = ROOT / "web" / "node_modules"


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The bin folder of a fresh venv with the wheel built from this checkout."""
    if not (NODE_MODULES / "three" / "build" / "three.module.js").is_file():
        pytest.skip("the wheel carries web/node_modules' libraries: run npm ci --prefix web")
    top = tmp_path_factory.mktemp("wheel")
    # No PYTHONPATH: a checkout on it would be taken for pliant already installed.
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", str(ROOT), "--no-deps",
                    "-w", str(top / "dist")], check=True, capture_output=True, timeout=600,
                   env=env)
    (wheel,) = (top / "dist").glob("pliant-*.whl")
    subprocess.run([sys.executable, "-m", "venv", str(top / "venv")], check=True,
                   timeout=300, env=env)
    bin_ = top / "venv" / "bin"
    # The dependencies are this environment's (installing them again from the index
    # took 30 s; CI's own install resolves the same list): its site-packages on the new
    # one's path, after the new one's own. Its .pth files are not read from there, so
    # this checkout's editable pliant stays out: pliant comes from the wheel alone.
    (site,) = (top / "venv" / "lib").glob("python*/site-packages")
    (site / "dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run([str(bin_ / "pip"), "install", "-q", "--no-deps", str(wheel)], check=True,
                   capture_output=True, timeout=900, env=env)
    return bin_


def _env(bin_: Path, home: Path) -> dict[str, str]:
    """The wheel's venv first on a path with no Node or npm; its own caches."""
    path = [str(bin_)] + [p for p in os.environ.get("PATH", "").split(os.pathsep)
                          if p and not (Path(p) / "node").exists()
                          and not (Path(p) / "npm").exists()]
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR", "PLIANT_CACHE", "VIRTUAL_ENV")}
    env.update(PATH=os.pathsep.join(path), PLIANT_CACHE=str(home / "cache"), HOME=str(home))
    return env


DEMO = """
import json, sys
from numba.core import event
from typer.testing import CliRunner
from pliant.cli.app import app
from pliant.models import first_run
ahead, late = [], []
compile_ahead = first_run.compile_ahead
def timed(*args, **kwargs):
    out = compile_ahead(*args, **kwargs)
    ahead.append(True)
    return out
first_run.compile_ahead = timed
class Late(event.Listener):
    def on_start(self, ev):
        if ahead:
            f = ev.data["dispatcher"].py_func
            late.append(f"{f.__module__}.{f.__qualname__}")
    def on_end(self, ev):
        pass
event.register("numba:compile", Late())
cold = first_run.cold("3d")
result = CliRunner().invoke(app, ["demo", "--out", sys.argv[1]])
print(json.dumps({"cold": cold, "exit": result.exit_code, "output": result.output,
                  "ahead": bool(ahead), "late": late, "cold_after": first_run.cold("3d")}))
"""


def test_the_wheel_runs_the_demo_and_serves_the_page(installed, tmp_path):
    env = _env(installed, tmp_path)
    assert shutil.which("node", path=env["PATH"]) is None
    version = subprocess.run([str(installed / "pliant"), "--version"], cwd=tmp_path,
                             env=env, capture_output=True, text=True, timeout=120)
    assert version.returncode == 0 and version.stdout.startswith("pliant ")
    where = subprocess.run([str(installed / "python"), "-c",
                            "import pliant; print(pliant.__file__)"],
                           cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert Path(where.stdout.strip()).is_relative_to(installed.parent)  # the wheel's
    # The demo as a fresh install's first run: the 3D kernels compiled ahead on two
    # cores by the signatures the wheel carries (models.first_run), then nothing left
    # for the job to compile (the first run's own test, for 3D, here where it is real).
    demo = subprocess.run([str(installed / "python"), "-c", DEMO, "out"], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=900)
    assert demo.returncode == 0, demo.stderr[-2000:]
    facts = json.loads(demo.stdout.strip().splitlines()[-1])
    assert facts["cold"] and facts["exit"] == 0, facts["output"]
    assert "compiling the 3D solvers (first run only" in facts["output"]
    assert facts["ahead"] and facts["late"] == [], f"the job compiled {facts['late']}"
    assert not facts["cold_after"]
    (site,) = installed.parent.glob("lib/python*/site-packages")
    assert (site / "pliant" / "models" / "kernel_signatures.pkl").is_file()
    cached = {p.name.split(".")[1].rsplit("-", 1)[0] for p in (site / "pliant").rglob("*.nbi")}
    assert {name for _, name in first_run.recorded("3d")["signatures"]} <= cached
    for suffix in ("html", "json", "csv", "png", "glb"):
        assert (tmp_path / "out" / f"engine_bay.{suffix}").stat().st_size > 0
    report = json.loads((tmp_path / "out" / "engine_bay.json").read_text())
    assert report["steps_solved"] == 101 and report["verdict"]["passes"]
    # The README's examples travel with the wheel: copied out, the same files.
    copied = subprocess.run([str(installed / "pliant"), "examples", "ex"], cwd=tmp_path,
                            env=env, capture_output=True, text=True, timeout=120)
    assert copied.returncode == 0, copied.stderr[-2000:]
    for name in ("scenes/hose_past_post.toml", "scenes/engine_bay.toml",
                 "cad/bracket_assembly.step", "identify/hose_bench.toml"):
        assert (tmp_path / "ex" / name).read_bytes() == (ROOT / "examples" / name).read_bytes()
    # The page, with the three.js it carries (no web/node_modules out here).
    view = subprocess.Popen([str(installed / "pliant"), "view", "--port", "0"],
                            cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        line = ""
        deadline = time.monotonic() + 120
        while "http://127.0.0.1:" not in line and time.monotonic() < deadline:
            line = view.stdout.readline()
        url = line[line.index("http://127.0.0.1:"):].split()[0]
        with urllib.request.urlopen(url, timeout=30) as page:
            assert b"importmap" in page.read()
        with urllib.request.urlopen(url.rstrip("/") + "/vendor/three/build/three.module.js",
                                    timeout=30) as lib:
            assert lib.status == 200 and len(lib.read()) > 100_000
    finally:
        view.send_signal(signal.SIGINT)
        try:
            view.wait(timeout=60)
        except subprocess.TimeoutExpired:
            view.kill()
            view.wait()
            raise
        finally:
            view.stdout.close()
    assert view.returncode in (0, 130)
