"""Features where they meet (issue 61): scenes that combine two features at a time, each
checked against a value pliant did not compute the same way (the primitive twin of a
mesh, the frictionless limit, the condition a fixed clip stands for, the rigid limit of
a fitted part, the inextensible limit, the planar model, the page against the CLI).

Each case returns ``Outcome``: ``right`` (the check holds), ``wrong`` (it does not),
``refused`` (a typed error: said, not wrong, but a combination that should work), or
``fallback`` (the answer rests on a part held rigid, ``HeldRigid``). ``CASES`` lists
them with ``fast`` for the CI subset; ``benchmarks/combinations.py`` runs them all and
prints counts per pair.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import pliant as pl
from pliant.core.events import HeldRigid, has
from pliant.errors import PliantError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@dataclass(frozen=True)
class Outcome:
    pair: tuple[str, str]
    name: str
    status: str  # right, wrong, refused, fallback
    detail: str


@dataclass(frozen=True)
class Case:
    pair: tuple[str, str]
    name: str
    run: Callable[[Path], tuple[bool, str]]
    fast: bool


def outcome(case: Case, folder: Path) -> Outcome:
    """Run one case in ``folder`` (its files), its errors and fallbacks as statuses."""
    try:
        ok, detail = case.run(folder)
    except _Fallback as err:
        return Outcome(case.pair, case.name, "fallback", str(err))
    except PliantError as err:
        return Outcome(case.pair, case.name, "refused", f"{type(err).__name__}: {err}")
    return Outcome(case.pair, case.name, "right" if ok else "wrong", detail)


class _Fallback(Exception):
    """An answer a case compared rested on a part held rigid."""


def _no_fallback(*eqs) -> None:
    for eq in eqs:
        if has(eq.notes, HeldRigid):
            raise _Fallback(next(n for n in eq.notes if isinstance(n, HeldRigid)))


def _load(text: str, folder: Path, name: str = "scene.toml"):
    from pliant.assembly.scenes import load_scene

    path = folder / name
    path.write_text(text)
    return load_scene(path)


def _solve(problem, elements: int = 60):
    from pliant.models import rod3d

    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=elements))
    _no_fallback(eq)
    return eq


# -- units x meshes, meshes x a path -------------------------------------------------------
# A hose clamped along +x, its end carried sideways round a vertical post (radius 5 cm):
# it wraps the post's side, every answer stable (a hose draped over a ball's top is
# not: it would slide off sideways, and a faceted ball seats it where a sphere cannot,
# so a ball is no twin for a mesh).
HOSE_BY_POST = """
name = "hose round a post"
gravity = [0.0, 0.0, -9.81]
{units}
[part]
name = "hose"
length = 1.0
outer_diameter = 0.02
bending_stiffness = 0.05
mass_per_length = 0.3
[solver]
elements = 100
[[condition]]
name = "clamp"
s = 0.0
x = 0.0
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[condition]]
name = "hand"
s = 1.0
x = {x}
y = {y}
z = 0.0
[[obstacle]]
name = "post"
{post}
"""
POST_AT = (0.5, 0.08, 0.0)
START, END = (0.95, 0.0), (0.9, 0.3)


def _write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """A mesh as an OBJ file, every digit written (an STL's float32 would round it)."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(vertices).tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(faces).tolist()]
    path.write_text("\n".join(lines) + "\n")


def _post_mesh(folder: Path, sections: int, unit: float, name: str) -> str:
    """A post as an OBJ file in ``unit`` [m] (every digit: the two units round alike)."""
    import trimesh

    post = trimesh.creation.cylinder(radius=0.05, height=0.4, sections=sections)
    _write_obj(folder / name, (post.vertices + np.array(POST_AT)) / unit, post.faces)
    return f'shape = "mesh"\nfile = "{name}"'


PRIMITIVE_POST = (f'shape = "cylinder"\nradius = 0.05\nlength = 0.4\n'
                  f"position = {list(POST_AT)}")


def facet_angle(sections: int) -> float:
    """The angle [rad] between neighbouring side faces' normals of a post of
    ``sections``: how far a facet's normal may lean from the cylinder's, the first-order
    error of a contact force's direction on it."""
    return 2.0 * math.pi / sections


def units_reach_meshes_once(folder: Path) -> tuple[bool, str]:
    """A post as a mesh file in millimetres under ``units = "mm"`` is the same obstacle
    as the same post written in metres (read in its own unit exactly once: the same
    path to round-off; scaled twice it would be a grain), and the hose carried round it
    has the primitive cylinder's hand force at every step to within the faceting's
    first-order error (the facet angle)."""
    sections = 128
    mm = _carried_round(folder, _post_mesh(folder, sections, 1e-3, "mm.obj"), "mm.toml",
                        25, units='units = "mm"')
    m = _carried_round(folder, _post_mesh(folder, sections, 1.0, "m.obj"), "m.toml", 25)
    for a, b in zip(mm.steps, m.steps):
        if not np.allclose(a.force, b.force, rtol=1e-9, atol=1e-12):
            return False, f"mm and m meshes differ: {a.force} against {b.force}"
    if not mm.steps[-1].contacts:
        return False, "the hose does not press on the post"
    exact = _carried_round(folder, PRIMITIVE_POST, "prim.toml", 25, units='units = "mm"')
    error = max(float(np.linalg.norm(np.subtract(a.force, b.force)) / np.linalg.norm(a.force))
                for a, b in zip(exact.steps, mm.steps))
    return error < facet_angle(sections), (
        f"mm = m to round-off; hand force off the primitive's by at most {error:.2%} "
        f"(facet angle {facet_angle(sections):.3f} rad)")


def _carried_round(folder: Path, post: str, name: str, steps: int, units: str = ""):
    from pliant.assembly.path import follow_path

    text = HOSE_BY_POST.format(units=units, x=START[0], y=START[1], post=post)
    text += f"[path]\ngrip = \"hand\"\nwaypoints = [[{END[0]}, {END[1]}, 0.0]]\nsteps = {steps}\n"
    scene = _load(text, folder, name)
    run = follow_path(scene.problem, scene.path, "hand", elements=100)
    if run.stopped:
        raise PliantError(run.stopped)
    _no_fallback(*run.equilibria)
    return run


def _path_over_mesh(folder: Path, sections: tuple[int, ...], steps: int
                    ) -> tuple[bool, str]:
    exact = _carried_round(folder, PRIMITIVE_POST, "prim.toml", steps)
    if not all(r.stable for r in exact.steps):
        return False, "the primitive's path is not stable throughout: no twin"
    errors = []
    for n in sections:
        run = _carried_round(folder, _post_mesh(folder, n, 1.0, f"post{n}.obj"),
                             f"post{n}.toml", steps)
        errors.append(max(float(np.linalg.norm(np.subtract(a.force, b.force))
                                / np.linalg.norm(a.force))
                          for a, b in zip(exact.steps, run.steps)))
    ok = all(e < facet_angle(n) for e, n in zip(errors, sections))
    return ok, "hand force off the primitive's by at most " + ", ".join(
        f"{e:.2%} ({n} sections, facet angle {facet_angle(n):.4f})"
        for e, n in zip(errors, sections))


def meshes_follow_a_path_as_their_primitive(folder: Path) -> tuple[bool, str]:
    """A hose carried round a post in 25 steps: over posts of 32 and 128 sections every
    step solves and the hand force is the cylinder's at every step to within the
    faceting's first-order error (the facet angle)."""
    return _path_over_mesh(folder, (32, 128), 25)


def dense_meshes_follow_a_path_as_their_primitive(folder: Path) -> tuple[bool, str]:
    """The same path round posts of 1,024 and 4,096 sections (CAD is that fine)."""
    return _path_over_mesh(folder, (1024, 4096), 25)


def meshes_of_1e5_triangles_follow_a_path_as_their_primitive(folder: Path
                                                             ) -> tuple[bool, str]:
    """The same path round a post of 32,768 sections (131,072 triangles)."""
    return _path_over_mesh(folder, (32768,), 25)


# -- clips --------------------------------------------------------------------------------------
def _clip_scene(friction: float, steps: int = 8) -> str:
    text = (EXAMPLES / "scenes" / "cable_through_clip.toml").read_text()
    text = text.replace('kind = "sliding"', f'kind = "sliding"\nfriction = {friction!r}'
                        if friction else 'kind = "sliding"')
    return text.replace("steps = 30", f"steps = {steps}")


def _carried(scene, elements: int = 80):
    from pliant.assembly.path import follow_path

    run = follow_path(scene.problem, scene.path, scene.grip, elements=elements)
    if run.stopped:
        raise PliantError(run.stopped)
    _no_fallback(*run.equilibria)
    return run


def clip_friction_has_its_frictionless_limit(folder: Path) -> tuple[bool, str]:
    """A sliding clip with a friction coefficient of 1e-3: the hand's force differs from
    the frictionless clip's by no more than that coefficient times the clip's normal
    reaction (what friction can add), at every step."""
    free = _carried(_load(_clip_scene(0.0), folder, "free.toml"))
    rough = _carried(_load(_clip_scene(1e-3), folder, "rough.toml"))
    worst = 0.0
    for a, b in zip(free.equilibria, rough.equilibria):
        clip = float(np.linalg.norm(a.loads["sliding clip"].force))
        change = float(np.linalg.norm(np.subtract(a.loads["hand"].force,
                                                  b.loads["hand"].force)))
        worst = max(worst, change / max(1e-3 * clip, 1e-12))
    return worst <= 1.0, f"hand force change up to {worst:.2f} of mu |R_clip|"


FIXED_AS_CLIP = """
[[clip]]
name = "clip"
s = 0.4
position = [0.38, 0.0, 0.05]
axis = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
"""
FIXED_AS_CONDITION = """
[[condition]]
name = "clip"
s = 0.4
x = 0.38
y = 0.0
z = 0.05
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
"""


def _cable(extra: str) -> str:
    text = (EXAMPLES / "scenes" / "cable_through_clip.toml").read_text()
    head = text[:text.index("[[clip]]")]
    hand = text[text.index('[[condition]]\nname = "hand"'):text.index("[path]")]
    return head + extra + hand


def fixed_clip_is_the_condition_it_stands_for(folder: Path) -> tuple[bool, str]:
    """A fixed clip with its normal is a condition holding position, axis and roll: the
    same answer, to round-off, and the same reaction under its name."""
    a = _solve(_load(_cable(FIXED_AS_CLIP), folder, "clip.toml").problem, 80)
    b = _solve(_load(_cable(FIXED_AS_CONDITION), folder, "cond.toml").problem, 80)
    diff = float(np.max(np.abs(a.position - b.position)))
    force = float(np.linalg.norm(np.subtract(a.loads["clip"].force, b.loads["clip"].force)))
    return diff < 1e-9 and force < 1e-7, f"shapes {diff:.1e} m apart, reactions {force:.1e} N"


def turning_clip_takes_no_moment_about_its_axis(folder: Path) -> tuple[bool, str]:
    """A turning clip lets the part turn about its axis: its moment about the axis is 0
    (round-off of the part's moment scale EI / L), where the fixed one's is not."""
    turning = FIXED_AS_CLIP.replace('normal = [0.0, 0.0, 1.0]\n', 'kind = "turning"\n')
    a = _solve(_load(_cable(turning), folder, "turning.toml").problem, 80)
    moment = float(np.dot(a.loads["clip"].moment, (1.0, 0.0, 0.0)))
    scale = 0.05 / 0.8
    return abs(moment) < 1e-9 * scale, f"moment about the axis {moment:.1e} N m"


# -- fitted parts ---------------------------------------------------------------------------------
def _fitted_scene(folder: Path, stiffness: float, flexible: bool):
    hose = (EXAMPLES / "scenes" / "coolant_hose.toml").read_text().replace(
        "bending_stiffness = 0.25", f"bending_stiffness = {stiffness!r}")
    (folder / "hose.toml").write_text(hose)
    line = (EXAMPLES / "scenes" / "line_over_hose.toml").read_text().replace(
        'file = "coolant_hose.toml"', f'file = "hose.toml"\nflexible = {str(flexible).lower()}')
    return _load(line, folder, "line.toml")


def stiff_fitted_part_tends_to_the_rigid_limit(folder: Path) -> tuple[bool, str]:
    """A fitted hose 100, 1,000 and 10,000 times stiffer than the coolant hose gives
    way as 1 / EI: where the line touches it, the line's hand force approaches its
    limit at first order (ten times nearer for ten times the stiffness). (Against the
    hose held rigid, flexible = false, the twin is not the same shape: its tube is a
    16-sided mesh.)"""
    forces = []
    for stiffness in (25.0, 250.0, 2500.0):
        run = _carried(_fitted_scene(folder, stiffness, True), 60)
        forces.append(run)
    touching = [k for k, eq in enumerate(forces[-1].equilibria) if eq.fitted]
    if not touching:
        return False, "the line never touched the fitted hose"
    k = touching[-1]
    f = [np.asarray(r.equilibria[k].loads["hand"].force) for r in forces]
    far, near = (float(np.linalg.norm(x - f[2]) / np.linalg.norm(f[2])) for x in f[:2])
    ratio = far / max(near, 1e-300)
    return 5.0 < ratio < 20.0, (f"step {k}: hand force {far:.1e} and {near:.1e} from the "
                                f"stiffest's (ratio {ratio:.1f})")


# -- stretch ------------------------------------------------------------------------------------
def stretch_has_its_inextensible_limit(folder: Path) -> tuple[bool, str]:
    """A part that stretches tends to the inextensible one as its axial stiffness grows,
    at first order (its strain F / EA): the hand's force changes by ten times less for
    ten times the stiffness, and by about the strain at EA = 1e7 N (EA L^2 / EI = 2e8, a
    steel cable's contrast, whose residual's round-off floor is above the default
    tolerance: it used to be refused)."""
    text = (EXAMPLES / "hoses" / "hose3d.toml").read_text()
    base = np.asarray(_solve(_load(text, folder, "inext.toml").problem).loads["hand"].force)
    changes = []
    for ea in (1e6, 1e7):
        stretched = text.replace("[part]\n", f"[part]\naxial_stiffness = {ea!r}\n", 1)
        force = _solve(_load(stretched, folder, "ext.toml").problem).loads["hand"].force
        changes.append(float(np.linalg.norm(base - force) / np.linalg.norm(base)))
    ratio = changes[0] / changes[1]
    return 8.0 < ratio < 12.0 and changes[1] < 1e-6, (
        f"hand force changes by {changes[0]:.1e} (EA 1e6 N) and {changes[1]:.1e} (1e7 N)")


# -- a box as a mesh, under each feature -------------------------------------------------------
# A box primitive is its 12-triangle mesh exactly (tests/test_distance.py): the same
# answer through the other's code (triangles, box tree, pseudonormals, the crease test
# that keeps its edges sharp), to the solver's tolerance, wherever a feature meets it.
def _box_text(name: str, size, centre, mesh: str | None) -> str:
    where = f"position = {[float(c) for c in centre]}\n"
    if mesh is None:
        return (f'\n[[obstacle]]\nname = "{name}"\nshape = "box"\n'
                f"size = {[float(c) for c in size]}\n" + where)
    return f'\n[[obstacle]]\nname = "{name}"\nshape = "mesh"\nfile = "{mesh}"\n' + where


def _box_mesh(folder: Path, size, name: str) -> str:
    import trimesh

    box = trimesh.creation.box(extents=size)
    _write_obj(folder / name, box.vertices, box.faces)
    return name


def _boxed(folder: Path, text: str, name: str, elements: int, size=(0.06, 0.06, 0.04),
           push: float = 0.003):
    """``text``'s part lifted ``push`` [m] at its lowest point by a box under it: the box
    as a primitive and as its mesh give the same loads at every station and the same
    force on the box, and the box does press. Returns (ok, what, the mesh's answer)."""
    free = _solve(_load(text, folder, f"{name}-free.toml").problem, elements)
    # its lowest point away from the stations that hold it (a box there would press
    # on the clamp, not on the part)
    held = [c.s for c in free.problem.conditions if any(v is not None for v in c.position)]
    length = free.problem.part.length
    away = np.array([min((abs(s - h) for h in held), default=length) > 0.1 * length
                     for s in free.s])
    low = int(np.flatnonzero(away)[np.argmin(free.position[away, 2])])
    x, y, z = free.position[low]
    top = z - free.problem.part.tube_radius + push
    centre = (x, y, top - 0.5 * size[2])
    mesh = _box_mesh(folder, size, f"{name}-box.obj")
    a = _solve(_load(text + _box_text("box", size, centre, None), folder,
                     f"{name}-primitive.toml").problem, elements)
    b = _solve(_load(text + _box_text("box", size, centre, mesh), folder,
                     f"{name}-mesh.toml").problem, elements)
    pressed = [float(np.linalg.norm(e.contacts.by_obstacle().get("box", np.zeros(3))))
               for e in (a, b)]
    if min(pressed) <= 0.0:
        return False, f"the box does not press ({pressed[0]:.3g}, {pressed[1]:.3g} N)", b
    scale = max(float(np.linalg.norm(ld.force)) for ld in a.loads.values())
    worst = max(float(np.linalg.norm(np.subtract(a.loads[k].force, b.loads[k].force)))
                for k in a.loads)
    box = abs(pressed[0] - pressed[1])
    ok = worst <= 1e-6 * scale and box <= 1e-6 * max(pressed)
    return ok, (f"the box presses {pressed[0]:.4g} N; loads {worst:.1e} N and the box's "
                f"force {box:.1e} N apart (largest load {scale:.3g} N)"), b


def _on_a_box(folder: Path, text: str, name: str, elements: int, **box) -> tuple[bool, str]:
    return _boxed(folder, text, name, elements, **box)[:2]


def branches_rest_on_a_mesh_as_on_its_primitive(folder: Path) -> tuple[bool, str]:
    """A harness trunk whose two branches meet it at a junction, lifted by a box under
    the junction (its lowest point); the parts solved together used to stop there ("no
    equilibrium of the parts together"): the obstacles' touching sets changed inside a
    Newton that held only the parts' own."""
    harness = EXAMPLES / "harness"
    for other in ("branch_left.toml", "branch_right.toml"):
        (folder / other).write_text((harness / other).read_text())
    text = (harness / "harness_y.toml").read_text()
    ok, detail, eq = _boxed(folder, text[:text.index("[path]")], "branch", 40)
    # Newton's law on the trunk: its stations' and junctions' loads, the box's push and
    # its weight add up to nothing.
    part = eq.problem.part
    weight = np.asarray(eq.problem.gravity) * part.mass_per_length * part.length
    total = sum(np.asarray(ld.force) for ld in eq.loads.values()) + weight + sum(
        eq.contacts.by_obstacle().values())
    off = float(np.linalg.norm(total))
    return ok and off < 1e-6, f"{detail}; the trunk's forces add up to {off:.1e} N"


def a_stretching_part_rests_on_a_mesh_as_on_its_primitive(folder: Path) -> tuple[bool, str]:
    """A hose that stretches (EA = 1e4 N: 0.1 mm a newton over its metre) lifted by a
    box."""
    text = (EXAMPLES / "hoses" / "hose3d.toml").read_text().replace(
        "[part]\n", "[part]\naxial_stiffness = 1e4\n", 1)
    return _on_a_box(folder, text, "stretch", 60)


def a_clipped_part_rests_on_a_mesh_as_on_its_primitive(folder: Path) -> tuple[bool, str]:
    """A cable through a sliding clip with friction, lifted by a box."""
    text = _clip_scene(0.2)
    return _on_a_box(folder, text[:text.index("[path]")], "clip", 80)


def a_fitted_part_and_a_mesh_as_a_primitive(folder: Path) -> tuple[bool, str]:
    """A cable resting on a fitted hose that gives way (the two solved together),
    lifted by a box elsewhere along it."""
    scenes = EXAMPLES / "scenes"
    (folder / "hose_across.toml").write_text((scenes / "hose_across.toml").read_text())
    text = (scenes / "cable_on_fitted_hose.toml").read_text()
    return _on_a_box(folder, text, "fitted", 40, size=(0.04, 0.06, 0.04), push=0.002)


# -- stretch, under each feature -----------------------------------------------------------------
def _tends_to_inextensible(folder: Path, text: str, name: str, elements: int,
                           station: str) -> tuple[bool, str]:
    """``text``'s part made extensible (EA = 1e5 and 1e6 N): the load at ``station``
    tends to the inextensible part's at first order in its strain F / EA (ten times
    nearer for ten times the stiffness)."""
    base = np.asarray(_solve(_load(text, folder, f"{name}-inext.toml").problem,
                             elements).loads[station].force)
    changes = []
    for ea in (1e5, 1e6):
        stretched = text.replace("[part]\n", f"[part]\naxial_stiffness = {ea!r}\n", 1)
        force = _solve(_load(stretched, folder, f"{name}-{ea:g}.toml").problem,
                       elements).loads[station].force
        changes.append(float(np.linalg.norm(base - force) / np.linalg.norm(base)))
    ratio = changes[0] / max(changes[1], 1e-300)
    return 7.0 < ratio < 13.0, (f"the {station}'s force changes by {changes[0]:.1e} (EA 1e5 "
                                f"N) and {changes[1]:.1e} (1e6 N): ratio {ratio:.1f}")


def branches_stretch_to_their_inextensible_limit(folder: Path) -> tuple[bool, str]:
    """A harness trunk that stretches, with its two branches at a junction."""
    harness = EXAMPLES / "harness"
    for other in ("branch_left.toml", "branch_right.toml"):
        (folder / other).write_text((harness / other).read_text())
    text = (harness / "harness_y.toml").read_text()
    return _tends_to_inextensible(folder, text[:text.index("[path]")], "branch", 40,
                                  "connector")


def a_clipped_part_stretches_to_its_inextensible_limit(folder: Path) -> tuple[bool, str]:
    """A cable through a sliding clip with friction that stretches."""
    text = _clip_scene(0.2)
    return _tends_to_inextensible(folder, text[:text.index("[path]")], "clip", 80, "hand")


def a_fitted_part_and_stretch_tend_to_the_inextensible_limit(folder: Path
                                                              ) -> tuple[bool, str]:
    """A cable that stretches, resting on a fitted hose that gives way."""
    scenes = EXAMPLES / "scenes"
    (folder / "hose_across.toml").write_text((scenes / "hose_across.toml").read_text())
    text = (scenes / "cable_on_fitted_hose.toml").read_text()
    return _tends_to_inextensible(folder, text, "fitted", 40, "hand")


# -- 2D x 3D ------------------------------------------------------------------------------------
def planar_problem_is_the_same_in_both_models(folder: Path) -> tuple[bool, str]:
    """The paper's case 1 (a cantilever under a dead tip force and moment, bent through
    a large angle) solved by the 2D elastica and by the 3D rod in the plane z = 0: the
    same tip and the same clamp moment, to the 3D model's discretisation (second order:
    400 elements)."""
    from pliant.io.problem_file import load_problem

    flat = load_problem(EXAMPLES / "paper" / "case1.toml")
    eq2 = pl.solve(flat)
    tip = next(c for c in flat.conditions if c.name == "tip load")
    fx, fy = (float(f) for f in tip.force)
    space = pl.Problem(flat.part, (
        pl.Condition(s=0.0, name="clamp", position=(0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0),
                     normal=(0.0, 0.0, 1.0)),
        pl.Condition(s=tip.s, name="tip load", force=(fx, fy, 0.0),
                     moment=(0.0, 0.0, float(tip.moment)))), gravity=(0.0, 0.0, 0.0))
    eq3 = _solve(space, 400)
    end2 = np.asarray(eq2.position[-1], float)[:2]
    end3 = np.asarray(eq3.position[-1])
    moment2 = float(eq2.loads["clamp"].moment)
    moment3 = float(eq3.loads["clamp"].moment[2])
    tip_error = float(np.linalg.norm(end2 - end3[:2])) + abs(float(end3[2]))
    moment_error = abs(moment2 - moment3) / abs(moment2)
    return tip_error < 1e-4 and moment_error < 1e-4, (
        f"tips {tip_error:.1e} m apart, clamp moments within {moment_error:.1e}")


# -- the page x the CLI ---------------------------------------------------------------------------
def page_and_cli_give_one_verdict(folder: Path) -> tuple[bool, str]:
    """The browser environment's verdict of a scene's pose (``evaluate_pose`` on the
    session's accurate answer) is ``pliant evaluate``'s of that pose: the same headline,
    the same force at the hand and the same clearances."""
    from pliant.assembly.evaluate import evaluate
    from pliant.assembly.scenes import load_scene
    from pliant.viewer.state import ViewerState

    scene = load_scene(EXAMPLES / "scenes" / "hose_past_post.toml")
    cli = evaluate(scene, search=False)
    viewer = ViewerState(Path("hose_past_post.toml"), EXAMPLES / "scenes", live=False)
    try:
        from pliant.viewer import protocol

        replies = viewer.handle(protocol.ClientHello(type="hello"))
        accurate = [r for r in replies if r.type == "accurate"][-1]
    finally:
        viewer.close()
    hand = next(x for x in accurate.loads if x.name == "hand")
    force = float(np.linalg.norm(np.subtract(hand.force, cli.run.equilibria[0].loads["hand"]
                                             .force)))
    page = {c.obstacle: c.clearance for c in accurate.interference.clearances}
    ours = dict(cli.run.steps[0].clearances)
    same_clear = all(abs(page[k] - ours[k]) < 1e-9 for k in ours)
    same = (accurate.verdict is not None and accurate.verdict.headline == cli.verdict.headline)
    return same and force < 1e-6 and same_clear, (
        f"headlines {'agree' if same else 'differ'}; hand force {force:.1e} N apart; "
        f"clearances {'agree' if same_clear else 'differ'}")


CASES = [
    Case(("units", "mesh"), "units reach meshes once", units_reach_meshes_once, True),
    Case(("mesh", "path"), "meshes follow a path as their primitive",
         meshes_follow_a_path_as_their_primitive, True),
    Case(("mesh", "path"), "dense meshes follow a path as their primitive",
         dense_meshes_follow_a_path_as_their_primitive, True),
    Case(("mesh", "path"), "meshes of 1e5 triangles follow a path as their primitive",
         meshes_of_1e5_triangles_follow_a_path_as_their_primitive, False),
    Case(("clip", "friction"), "friction has its frictionless limit",
         clip_friction_has_its_frictionless_limit, True),
    Case(("clip", "condition"), "a fixed clip is the condition it stands for",
         fixed_clip_is_the_condition_it_stands_for, True),
    Case(("clip", "twist"), "a turning clip takes no moment about its axis",
         turning_clip_takes_no_moment_about_its_axis, True),
    Case(("fitted part", "path"), "a stiff fitted part tends to the rigid limit",
         stiff_fitted_part_tends_to_the_rigid_limit, False),
    Case(("stretch", "hand"), "stretch has its inextensible limit",
         stretch_has_its_inextensible_limit, True),
    Case(("branch", "mesh"), "branches rest on a mesh as on its primitive",
         branches_rest_on_a_mesh_as_on_its_primitive, True),
    Case(("stretch", "mesh"), "a stretching part rests on a mesh as on its primitive",
         a_stretching_part_rests_on_a_mesh_as_on_its_primitive, True),
    Case(("clip", "mesh"), "a clipped part rests on a mesh as on its primitive",
         a_clipped_part_rests_on_a_mesh_as_on_its_primitive, True),
    Case(("fitted part", "mesh"), "a fitted part and a mesh as a primitive",
         a_fitted_part_and_a_mesh_as_a_primitive, True),
    Case(("branch", "stretch"), "branches stretch to their inextensible limit",
         branches_stretch_to_their_inextensible_limit, True),
    Case(("clip", "stretch"), "a clipped part stretches to its inextensible limit",
         a_clipped_part_stretches_to_its_inextensible_limit, True),
    Case(("fitted part", "stretch"), "a fitted part and stretch tend to the inextensible limit",
         a_fitted_part_and_stretch_tend_to_the_inextensible_limit, True),
    Case(("2D", "3D"), "a planar problem is the same in both models",
         planar_problem_is_the_same_in_both_models, True),
    Case(("page", "CLI"), "the page and the CLI give one verdict",
         page_and_cli_give_one_verdict, True),
]
