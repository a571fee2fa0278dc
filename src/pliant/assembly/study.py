"""Variation studies: how robust is the verdict to the parts that will arrive?

``study(scene_file, variations, samples, out=folder)`` draws the sample plan
(``pliant.assembly.variation``), evaluates the scene's operation for every sample (the
full verdict of ``pliant.assembly.evaluate``) on Dask distributed, and writes each result
as it comes: a line of ``samples.jsonl`` per sample (its varied values, verdict, peak
grip force and moment, smallest clearance and bend radius, the final centreline, or the
error of a sample that failed) and the voxels its part swept along the path
(``voxels/N.npy``). The folder's ``study.json`` holds the plan; run the same study into
the same folder again and only the samples missing from it are computed.

Workers: with no address, a ``LocalCluster`` of one single-threaded worker process per
core on 127.0.0.1 (no dashboard); with ``scheduler="tcp://HOST:PORT"``, an existing
cluster; with ``workers=0``, in this process (no Dask: the serial twin the tests compare
with). Samples go in batches of a few, so that Dask's per-task cost stays small against
an evaluation's second; each worker process loads the compiled kernels once.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pliant.assembly.variation import Variation, apply, nominal_values, parse_variation, plan
from pliant.core.equilibrium import Equilibrium3D
from pliant.errors import InputError, PliantError
from pliant.io.jsonlines import JsonLines

STUDY_VERSION = 1


@dataclass(frozen=True)
class StudySpec:
    """Everything a worker needs to evaluate samples, picklable: the scene's document,
    where its files are, the variations and their nominal values, the voxel size [m]
    of the swept envelope and the resolution."""

    data: dict[str, Any]
    source: str
    base: str
    variations: tuple[Variation, ...]
    nominal: dict[str, Any]
    voxel: float
    elements: int | None = None
    search: bool = True


def _heap_kept() -> None:
    """Undo Dask's MALLOC_TRIM_THRESHOLD_ in this process (a worker of a cluster pliant
    did not start): glibc then hands freed memory back to the system at once and maps
    every array above 128 KiB afresh, and an evaluation, which allocates and frees such
    arrays at every Newton step, runs 1.3 to 1.6 times slower, more so with each
    sample. Larger thresholds keep the heap; nothing to do off glibc."""
    if not os.environ.get("MALLOC_TRIM_THRESHOLD_"):
        return
    import ctypes  # noqa: PLC0415

    try:
        libc = ctypes.CDLL(None)
        libc.mallopt(-1, 256 << 20)  # M_TRIM_THRESHOLD
        libc.mallopt(-3, 32 << 20)  # M_MMAP_THRESHOLD (glibc's largest)
    except (OSError, AttributeError):
        pass


_NOMINAL: dict[tuple, Any] = {}  # per process: each study's nominal start, solved once


def nominal_start(spec: StudySpec) -> Equilibrium3D:
    """The nominal scene's start pose, solved once per process: every sample starts from
    it (the same branch, in a few Newton iterations where a cold start takes about a
    second). None where it has no equilibrium (the samples then start cold)."""
    from pliant.assembly.scenes import scene_from_data  # noqa: PLC0415
    from pliant.models import rod3d  # noqa: PLC0415

    key = (spec.source, spec.elements, json.dumps(spec.data, sort_keys=True, default=str))
    if key not in _NOMINAL:
        try:
            scene = scene_from_data(spec.data, spec.source, Path(spec.base))
            solver = rod3d.RodSolver(elements=spec.elements or scene.solver.elements)
            _NOMINAL[key] = rod3d.solve(scene.problem, solver=solver)
        except (PliantError, ValueError, ArithmeticError):
            _NOMINAL[key] = None
    return _NOMINAL[key]


def evaluate_samples(spec: StudySpec, rows: list[tuple[int, list[float]]]
                     ) -> list[tuple[dict[str, Any], np.ndarray | None]]:
    """Evaluate each (index, deviations) sample: (its record, its swept voxels (k, 3)
    int32 or None). A sample that fails is recorded with its error; it never raises."""
    from pliant.assembly.evaluate import evaluate  # noqa: PLC0415 (loads the kernels)
    from pliant.assembly.scenes import scene_from_data  # noqa: PLC0415

    _heap_kept()
    start_from = nominal_start(spec)

    out = []
    for index, row in rows:
        start = time.perf_counter()
        values: dict[str, Any] = {}
        try:
            doc, values = apply(spec.data, list(spec.variations), spec.nominal,
                                np.asarray(row, float))
            scene = scene_from_data(doc, f"{spec.source} (sample {index})", Path(spec.base))
            ev = evaluate(scene, elements=spec.elements, search=spec.search,
                          start_from=start_from)
            record, voxels = _record(ev, spec.voxel)
            record.update(index=index, deviations=list(map(float, row)), values=values,
                          status="ok", error=None)
        except (PliantError, ValueError, ArithmeticError) as err:
            record, voxels = {"index": index, "deviations": list(map(float, row)),
                              "values": values, "status": "failed",
                              "error": f"{type(err).__name__}: {err}"}, None
        record["seconds"] = time.perf_counter() - start
        out.append((record, voxels))
    return out


def _record(ev: Any, voxel: float) -> tuple[dict[str, Any], np.ndarray]:
    run = ev.run
    grip = ev.run.grip  # the hand's (or, a part in its clamps, the first clamp's)
    forces = [float(np.linalg.norm(eq.loads[grip].force)) for eq in run.equilibria]
    moments = [float(np.linalg.norm(eq.loads[grip].moment)) for eq in run.equilibria]
    nearest = min(run.steps, key=lambda r: r.clearance)
    tightest = min(run.steps, key=lambda r: r.bend_radius)
    zones = {c.rule: c.zone.value for c in ev.checks}
    if ev.chosen is not None:
        zones.update({f"operator: {c.rule}": c.zone.value for c in ev.chosen.checks})
    points = np.concatenate([_dense(eq.position, voxel) for eq in run.equilibria])
    voxels = np.unique(np.floor(points / voxel).astype(np.int32), axis=0)
    return {
        "passes": ev.verdict.passes, "assemblable": ev.verdict.assemblable,
        "decided": ev.verdict.decided,
        "operator": ev.verdict.operator, "headline": ev.verdict.headline,
        "complete": run.complete, "steps_solved": len(run.steps),
        "peak_force": max(forces), "peak_force_step": int(np.argmax(forces)),
        "peak_moment": max(moments), "min_clearance": float(nearest.clearance),
        "nearest": nearest.nearest, "min_bend_radius": float(tightest.bend_radius),
        "zones": zones, "final": run.final.position.tolist(),
    }, voxels


def _dense(points: np.ndarray, spacing: float) -> np.ndarray:
    """The polyline ``points`` (n, 3) resampled at most ``spacing`` / 2 apart, so that
    every voxel it passes through holds a point."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    k = np.maximum(1, np.ceil(seg / (0.5 * spacing)).astype(np.int64))
    idx = np.repeat(np.arange(seg.shape[0]), k)
    first = np.repeat(np.cumsum(k) - k, k)
    t = (np.arange(int(k.sum())) - first) / np.repeat(k, k)
    dense = points[idx] + t[:, None] * (points[idx + 1] - points[idx])
    return np.concatenate([dense, points[-1:]])


# -- the store ----------------------------------------------------------------------------
class Store:
    """A study's folder: ``study.json`` (the plan), ``samples.jsonl`` (a line a sample,
    appended and flushed as results arrive; a line cut short by an interruption is
    dropped on reading and its sample computed again) and ``voxels/`` (each sample's
    swept voxels, written before its line)."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.lines = self.folder / "samples.jsonl"
        self.voxels = self.folder / "voxels"
        self.log = JsonLines(self.lines)

    def open(self, plan_record: dict[str, Any], restart: bool = False) -> set[int]:
        """Create or reopen the folder for ``plan_record``; the indices already done."""
        from pliant.io.atomic import atomic_write  # noqa: PLC0415

        self.folder.mkdir(parents=True, exist_ok=True)
        self.voxels.mkdir(exist_ok=True)
        meta = self.folder / "study.json"
        if meta.exists() and not restart:
            old = json.loads(meta.read_text())
            if old.get("key") != plan_record["key"]:
                raise InputError("out", f"{self.folder} holds another study (other scene, "
                                 "variations, samples, method or seed); choose another "
                                 "folder, or restart it")
            self._drop_torn_line()
            return {r["index"] for r in self.records()}
        if restart and self.lines.exists():
            self.lines.unlink()
        text = json.dumps(plan_record, indent=1).encode()
        atomic_write(meta, lambda h: h.write(text), "the study's plan")
        return set()

    def _drop_torn_line(self) -> None:
        self.log.drop_torn()

    def add(self, record: dict[str, Any], voxels: np.ndarray | None) -> None:
        from pliant.io.atomic import atomic_write  # noqa: PLC0415

        if voxels is not None:
            path = self.voxels / f"{record['index']}.npy"
            atomic_write(path, lambda h: np.save(h, voxels), "a sample's voxels")
        self.log.append(record)

    def records(self) -> list[dict[str, Any]]:
        """Every complete line (the last one, if an interruption cut it, is left out)."""
        out = {r["index"]: r for r in self.log.read()}
        return [out[k] for k in sorted(out)]

    def swept(self, indices: list[int]) -> np.ndarray:
        """The union of the samples' swept voxels (k, 3)."""
        parts = [np.load(self.voxels / f"{i}.npy") for i in indices
                 if (self.voxels / f"{i}.npy").exists()]
        if not parts:
            return np.zeros((0, 3), dtype=np.int32)
        return np.unique(np.concatenate(parts), axis=0)


# -- the driver ---------------------------------------------------------------------------
@dataclass
class StudyResult:
    """The study as run: its folder, the variations, the plan (samples, columns), the
    records by index (all of them, resumed ones included), and how many this run
    computed, on how many workers, in how many seconds."""

    folder: Path
    variations: list[Variation]
    columns: list[str]
    plan: np.ndarray
    records: list[dict[str, Any]]
    computed: int
    workers: int
    seconds: float
    voxel: float
    radius: float
    scene: Any = field(default=None, repr=False)

    @property
    def ok(self) -> list[dict[str, Any]]:
        return [r for r in self.records if r["status"] == "ok"]

    @property
    def failed(self) -> list[dict[str, Any]]:
        return [r for r in self.records if r["status"] != "ok"]


def study(scene_file: str | Path, variations: list[str], samples: int, *, out: str | Path,
          method: str = "lhs", seed: int = 0, scheduler: str | None = None,
          workers: int | None = None, batch: int | None = None,
          elements: int | None = None, restart: bool = False, search: bool = True,
          on_done: Callable[[int, int], None] | None = None) -> StudyResult:
    """Run (or resume) a variation study of a scene file; see the module."""
    from pliant.assembly.scenes import scene_from_data  # noqa: PLC0415
    from pliant.io.problem_file import read_text  # noqa: PLC0415
    from pliant.io.tomlfile import read_toml  # noqa: PLC0415

    scene_file = Path(scene_file)
    text = read_text(scene_file)  # read once: the document varied and the plan's key
    data = read_toml(text, str(scene_file))
    nominal_scene = scene_from_data(data, str(scene_file), scene_file.parent)
    parsed = [parse_variation(s, data, i) for i, s in enumerate(variations)]
    names = [v.name for v in parsed]
    if len(set(names)) != len(names):
        raise InputError("vary", "a parameter is varied twice; give each once")
    nominal = nominal_values(parsed, data, nominal_scene.problem.part)
    deviations = plan(parsed, samples, method, seed)
    columns = [c for v in parsed for c in v.columns]
    part = nominal_scene.problem.part
    radius = part.drawn_radius
    voxel = max(2.0 * radius, 1e-3)
    spec = StudySpec(data, str(scene_file), str(scene_file.resolve().parent), tuple(parsed),
                     nominal, voxel, elements, search)
    key = hashlib.sha256(json.dumps({
        "scene": text, "variations": [v.to_dict() for v in parsed], "samples": samples,
        "method": method, "seed": seed, "elements": elements, "search": search,
        "version": STUDY_VERSION}, sort_keys=True).encode()).hexdigest()
    from pliant.io.folder_lock import FolderLock  # noqa: PLC0415

    store = Store(Path(out))
    with FolderLock(out, "study"):  # one study at a time in a folder
        done = store.open({"key": key, "scene": str(scene_file), "variations": variations,
                           "samples": samples, "method": method, "seed": seed,
                           "columns": columns, "nominal": nominal, "voxel": voxel,
                           "version": STUDY_VERSION}, restart)
        todo = [k for k in range(samples) if k not in done]
        start = time.perf_counter()
        used = 0
        if todo:
            used = _run(spec, deviations, todo, store, scheduler, workers, batch,
                        lambda n: on_done(len(done) + n, samples) if on_done else None)
        elif on_done:
            on_done(samples, samples)
        records = store.records()
    return StudyResult(store.folder, parsed, columns, deviations, records, len(todo),
                       used, time.perf_counter() - start, voxel, radius, nominal_scene)


def _run(spec: StudySpec, deviations: np.ndarray, todo: list[int], store: Store,
         scheduler: str | None, workers: int | None, batch: int | None,
         progress: Callable[[int], None]) -> int:
    """Evaluate the samples ``todo``, storing each as it arrives; the workers used."""
    finished = 0
    if workers == 0 and scheduler is None:
        for k in todo:
            for record, voxels in evaluate_samples(spec, [(k, deviations[k].tolist())]):
                store.add(record, voxels)
                finished += 1
                progress(finished)
        return 0
    from distributed import as_completed  # noqa: PLC0415

    from pliant.assembly.cluster import dask_client, worker_count  # noqa: PLC0415

    with dask_client(scheduler, workers) as client:
        count = worker_count(client)
        size = batch or max(1, min(8, math.ceil(len(todo) / (4 * count))))
        batches = [todo[i:i + size] for i in range(0, len(todo), size)]
        remote = client.scatter(spec, broadcast=True)
        futures = {client.submit(evaluate_samples, remote,
                                 [(k, deviations[k].tolist()) for k in b], pure=False,
                                 retries=1): b for b in batches}
        for future in as_completed(futures):
            try:
                results = future.result()
            except Exception as err:
                results = [({"index": k, "deviations": deviations[k].tolist(), "values": {},
                             "status": "failed", "seconds": 0.0,
                             "error": f"the worker failed: {type(err).__name__}: {err}"},
                            None) for k in futures[future]]
            for record, voxels in results:
                store.add(record, voxels)
                finished += 1
                progress(finished)
        return count


# -- what it says -------------------------------------------------------------------------
OUTPUTS = (("peak_force", "peak grip force", "N"), ("peak_moment", "peak grip moment", "N m"),
           ("min_clearance", "smallest clearance", "m"),
           ("min_bend_radius", "smallest bend radius", "m"))


def summarize(result: StudyResult) -> dict[str, Any]:
    """Percentiles of the outputs, the probability of each verdict, and the sensitivity
    of each output (and of passing) to each varied column: Spearman's rank correlation
    over the samples that were evaluated, ranked by its largest magnitude."""
    from scipy.stats import spearmanr  # noqa: PLC0415

    ok = result.ok
    n = len(result.records)
    verdicts: dict[str, int] = {}
    for r in result.records:
        if r["status"] != "ok":
            key = "failed to evaluate"
        elif r["passes"]:
            key = f"passes: {r['operator']}"
        else:
            key = ("undecided (a fallback)" if not r.get("decided", True) else
                   "does not fit" if not r["assemblable"] else "no operator passes")
        verdicts[key] = verdicts.get(key, 0) + 1
    percentiles = {}
    for key, title, unit in OUTPUTS:
        values = np.array([r[key] for r in ok if r.get(key) is not None], float)
        values = values[np.isfinite(values)]
        percentiles[key] = {"title": title, "unit": unit, "count": int(values.size), **(
            {f"p{q}": float(np.percentile(values, q)) for q in (1, 5, 50, 95, 99)}
            | {"min": float(values.min()), "max": float(values.max())}
            if values.size else {})}
    sensitivity = []
    if len(ok) >= 3:
        X = np.array([r["deviations"] for r in ok], float)
        outputs = {key: np.array([r[key] if r.get(key) is not None else np.nan for r in ok],
                                 float) for key, _, _ in OUTPUTS}
        outputs["passes"] = np.array([1.0 if r["passes"] else 0.0 for r in ok])
        for j, column in enumerate(result.columns):
            row: dict[str, Any] = {"parameter": column}
            for key, y in outputs.items():
                good = np.isfinite(y)
                if good.sum() < 3 or np.ptp(y[good]) == 0.0 or np.ptp(X[good, j]) == 0.0:
                    row[key] = 0.0
                    continue
                row[key] = float(spearmanr(X[good, j], y[good]).statistic)
            sensitivity.append(row)
        sensitivity.sort(key=lambda r: -max(abs(v) for k, v in r.items() if k != "parameter"))
    return {
        "samples": n, "evaluated": len(ok), "failed": n - len(ok),
        "verdicts": {k: {"count": v, "probability": v / n} for k, v in
                     sorted(verdicts.items(), key=lambda kv: -kv[1])},
        "percentiles": percentiles, "sensitivity": sensitivity,
        "errors": [{"index": r["index"], "error": r["error"]} for r in result.failed][:50],
        "workers": result.workers, "computed": result.computed, "seconds": result.seconds,
    }


def final_voxels(result: StudyResult) -> np.ndarray:
    """The voxels (k, 3) the part fills at its final pose over all evaluated samples."""
    parts = [np.floor(_dense(np.array(r["final"]), result.voxel) / result.voxel)
             .astype(np.int32) for r in result.ok]
    if not parts:
        return np.zeros((0, 3), dtype=np.int32)
    return np.unique(np.concatenate(parts), axis=0)
