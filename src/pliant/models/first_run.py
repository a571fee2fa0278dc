"""The 3D solvers' first compile, on two cores instead of one.

numba compiles a kernel when it is first called and keeps it (``cache=True``), so only a
fresh install pays. Compiled lazily, one kernel after the other in the one process, the
bundled scene's first ``pliant demo`` spent 24 of its 27 s compiling on one core. Here
the kernels a 3D scene needs are compiled ahead, by the signatures they are called with
(``SIGNATURES``, recorded from a run), in two halves of about equal cost: this process
compiles ``OURS`` while a helper process (``python -m pliant.models.first_run``)
compiles ``THEIRS`` into the same cache, and this process waits for the helper before it
solves, so that nothing is compiled twice. Where the machine has one core, the cache is
warm, or the recorded signatures are not those the code now uses, the kernels compile
lazily as before: never wrong, at worst as slow as before. ``tests/test_first_run.py``
checks that after ``compile_ahead`` a scene's solve compiles nothing.

Record the signatures again after changing a kernel's arguments::

    python -m pliant.cli.record_kernels
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

SIGNATURES = Path(__file__).with_name("kernel_signatures.pkl")

# (module, kernel). A kernel compiles the kernels it calls with it unless they are
# cached, and the contact's kernels nest: the Newton solve calls the contact terms,
# which call the distance queries. That chain (about 12 s on one core of the machine
# measured) is this process's half, with the contact-free Newton solve after it; the
# helper takes everything else (about 15 s), the banded solvers first, which the Newton
# solves call and then find in the cache.
OURS: tuple[tuple[str, str], ...] = (
    ("pliant.scene.distance", "query_points"),
    ("pliant.models.rod3d.contact_kernels", "contact_terms"),
    ("pliant.models.rod3d.contact_kernels", "newton_contact"),
    # a scene's fitted parts, solved without contact on a fresh disk cache
    # (``pliant.util.cache``): last, when the helper has cached what they call
    ("pliant.models.rod3d.kernels", "newton"),
    ("pliant.models.banded", "band_solve"),
)
THEIRS: tuple[tuple[str, str], ...] = (
    ("pliant.models.banded", "band_lu"),
    ("pliant.models.banded", "identity_rows"),
    ("pliant.models.banded", "band_solve_reduced"),
    ("pliant.models.rod3d.kernels", "assemble"),
    ("pliant.models.rod3d.kernels", "rest_shape"),
    ("pliant.scene.triangles", "pseudonormal_sums"),
    ("pliant.scene.triangles", "build_bvh"),
    ("pliant.scene.grid", "band_values"),  # a mesh's distance grid, on a fresh disk cache
    ("pliant.models.rod3d.kernels", "apply_step"),
    ("pliant.models.rod3d.kernels", "difference"),
    ("pliant.models.rod3d.kernels", "unknown_sizes"),
    ("pliant.models.rod3d.contact_kernels", "contact_max"),
    ("pliant.models.rod3d.kernels", "node_outputs"),
    ("pliant.models.lanczos", "softest_mode"),
    ("pliant.scene.interference", "_polyline_distance"),
)
HELPER_TIMEOUT = 300.0  # s: past this the helper is stopped and the rest compiles lazily


def dispatcher(module: str, name: str) -> Any:
    return getattr(importlib.import_module(module), name)


def cold() -> bool:
    """Whether the 3D kernels are not cached yet (a fresh install, or a new
    ``NUMBA_CACHE_DIR``): numba keeps an index (.nbi) per kernel."""
    source = Path(__file__).resolve().parent / "rod3d"
    cache, pattern = source / "__pycache__", "kernels.*.nbi"
    if os.environ.get("NUMBA_CACHE_DIR"):  # numba keeps a folder per source folder there
        cache, pattern = Path(os.environ["NUMBA_CACHE_DIR"]), f"rod3d_*/{pattern}"
    return not any(cache.glob(pattern))


def _signatures() -> dict[tuple[str, str], list[Any]]:
    """The recorded signatures by kernel; empty where the file cannot be read with this
    numba (then everything compiles lazily)."""
    try:
        with SIGNATURES.open("rb") as f:
            data = pickle.load(f)  # our own file, shipped with the package
    except Exception:  # another numba's types: compile lazily instead
        return {}
    return data if isinstance(data, dict) else {}


def compile_kernels(kernels: Iterable[tuple[str, str]],
                    on_kernel: Callable[[str], None] | None = None,
                    signatures: dict[tuple[str, str], list[Any]] | None = None) -> int:
    """Compile (or load from the cache) each kernel for its recorded signatures (read
    from ``SIGNATURES`` unless given); the number compiled or loaded. A signature numba
    refuses is skipped: the kernel then compiles lazily for the one it is called with."""
    signatures = _signatures() if signatures is None else signatures
    done = 0
    for module, name in kernels:
        if on_kernel is not None:
            on_kernel(name)
        for signature in signatures.get((module, name), ()):
            try:
                dispatcher(module, name).compile(signature)
                done += 1
            except Exception:  # a stale signature: the kernel compiles lazily
                continue
    return done


def compile_ahead(on_kernel: Callable[[str], None] | None = None,
                  cores: int | None = None) -> bool:
    """Compile the 3D kernels a scene needs, half here and half in a helper process
    where the machine has a second core (see the module); True when a helper ran.
    ``on_kernel(name)`` is told each kernel this process starts."""
    cores = (os.cpu_count() or 1) if cores is None else cores
    helper = None
    if cores >= 2:
        try:
            helper = subprocess.Popen(
                [sys.executable, "-m", "pliant.models.first_run", str(os.getpid())],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL)
        except OSError:
            helper = None
    compile_kernels(OURS if helper is not None else OURS + THEIRS, on_kernel)
    if helper is None:
        return False
    if on_kernel is not None:
        on_kernel("the helper's half")
    try:
        helper.wait(timeout=HELPER_TIMEOUT)
    except subprocess.TimeoutExpired:
        helper.kill()
        helper.wait()
    return True


def _helper(parent: int) -> None:
    """The helper's work: its half, stopping early if the process that started it is
    gone (nothing would wait for it)."""
    signatures = _signatures()  # read once, not once a kernel
    for kernel in THEIRS:
        if os.getppid() != parent:
            return
        compile_kernels((kernel,), signatures=signatures)


if __name__ == "__main__":
    _helper(int(sys.argv[1]))
