"""The browser environment's wire protocol, defined once (version ``VERSION``).

Every message is one JSON object on the websocket with ``v`` (the protocol version) and
``type``. The browser sends the ``Client*`` messages; the server answers with the
``Server*`` ones. SI units throughout: positions in m, forces in N, moments in N m,
curvature in 1/m. Sizes are bounded: a message longer than ``MAX_MESSAGE`` bytes, or not
valid JSON, or not one of these messages, gets an ``error`` reply naming what is wrong,
and the connection stays open (the websocket layer itself closes a connection whose
message passes ``MAX_FRAME``, and the server goes on serving the others).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any, Final, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

from pliant.io.jsontext import finite

VERSION: Final = 1
MAX_MESSAGE = 64 * 1024  # bytes: the largest client message parsed
MAX_FRAME = 1024 * 1024  # bytes: the websocket layer closes a connection past this
NAME = r"^[A-Za-z0-9][A-Za-z0-9 _.-]{0,63}$"  # a session file's name (in the scene folder)

# A coordinate, tangent component or load: finite and within a million (m, N): a scene
# is metres across, and 1e308 only overflows the models.
Finite = Annotated[float, Field(allow_inf_nan=False, ge=-1e6, le=1e6)]
Vec3 = tuple[Finite, Finite, Finite]


class _Message(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    v: Literal[1] = VERSION


# -- browser -> server -----------------------------------------------------------------------
class ClientHello(_Message):
    """Ask for the scene (obstacles, part, grips) and the current frame."""

    type: Literal["hello"]


class ClientMove(_Message):
    """Move a grip held by position: its point [m] and, for a 3D grip that holds the
    part's direction, its unit tangent. ``seq`` is echoed in the frame that answers."""

    type: Literal["move"]
    grip: str = Field(max_length=64)
    position: Vec3
    tangent: Vec3 | None = None
    seq: int = Field(default=0, ge=0)


class ClientMode(_Message):
    """Switch a grip between holding by position (``position``) and pushing with a force
    (``force``: the force [N] and, in 3D, moment [N m] it applies to the part; both
    default to what it applies now, so the shape does not jump)."""

    type: Literal["mode"]
    grip: str = Field(max_length=64)
    mode: Literal["position", "force"]
    force: Vec3 | None = None
    moment: Vec3 | None = None


class ClientSolve(_Message):
    """Run an accurate solve at the current pose now."""

    type: Literal["solve"]


class ClientSave(_Message):
    """Save the session (the scene's name and every grip's pose and mode) to ``name``
    (a plain file name, ``.json`` added) in the scene's folder, written atomically."""

    type: Literal["save"]
    name: str = Field(pattern=NAME)


class ClientLoad(_Message):
    """Load a session saved in the scene's folder."""

    type: Literal["load"]
    name: str = Field(pattern=NAME)


class ClientEquilibria(_Message):
    """List the current pose's equilibria (``pliant.models.dispatch.equilibria``) within
    ``budget`` seconds; answered by an ``equilibria`` message when the accurate model is
    done."""

    type: Literal["equilibria"]
    budget: float = Field(default=10.0, gt=0.0, le=60.0)


class ClientChoose(_Message):
    """Make equilibrium ``option`` (0-based, of the last ``equilibria`` answer for this
    pose) the accurate answer and the branch the session follows from now on."""

    type: Literal["choose"]
    option: int = Field(ge=0, le=1000)


ClientMessage = Annotated[ClientHello | ClientMove | ClientMode | ClientSolve | ClientSave
                          | ClientLoad | ClientEquilibria | ClientChoose,
                          Field(discriminator="type")]
_CLIENT = TypeAdapter(ClientMessage)
CLIENT_MESSAGES: tuple[type[_Message], ...] = (
    ClientHello, ClientMove, ClientMode, ClientSolve, ClientSave, ClientLoad,
    ClientEquilibria, ClientChoose)


def _type_of(model: type[BaseModel]) -> str:
    """A message model's ``type``: a client's Literal, a server's default."""
    kind = model.model_fields["type"]
    return kind.default if isinstance(kind.default, str) else kind.annotation.__args__[0]  # type: ignore[union-attr]


TYPES = tuple(_type_of(m) for m in CLIENT_MESSAGES)


# -- server -> browser -----------------------------------------------------------------------
class Grip(BaseModel):
    """A condition the user can act on: where it is, what it holds, how it is driven."""

    name: str
    s: float
    position: list[float]
    tangent: list[float] | None
    mode: Literal["position", "force", "fixed"]
    force: list[float] | None = None
    moment: list[float] | None = None


class Load(BaseModel):
    """What a condition applies to the part: force [N], moment [N m] (3 components; a 2D
    moment is its z), at the point ``position`` [m]."""

    name: str
    position: list[float]
    force: list[float]
    moment: list[float]
    prescribed: list[bool]


class Span(BaseModel):
    obstacle: str
    s_start: float
    s_end: float
    worst: float


class Clearance(BaseModel):
    obstacle: str
    clearance: float
    s: float
    point: list[float]


class Interference(BaseModel):
    """Of a shape against the scene: the smallest clearance [m] per obstacle, spans that
    penetrate (worst: depth [m], negative) and spans nearer than the margin."""

    margin: float
    clearances: list[Clearance]
    penetrations: list[Span]
    too_close: list[Span]


class Contact(BaseModel):
    s: float
    point: list[float]
    force: list[float]
    obstacle: str


class ObstacleMesh(BaseModel):
    name: str
    vertices: list[list[float]]
    faces: list[list[int]]


class ServerFrame(_Message):
    """The real-time model's frame (answers a move at once): the curve [m] at s [m],
    its curvature [1/m], the points held out of obstacles, the interference of the tube,
    and the drift from the last accurate shape (relative to L)."""

    type: Literal["frame"] = "frame"
    seq: int
    index: int
    s: list[float]
    curve: list[list[float]]
    curvature: list[float]
    contacts: list[list[float]]
    interference: Interference
    converged: bool
    drift: float
    pending: bool
    seconds: float
    warnings: list[str] = []  # the preview's (``pliant.assembly.checks.shape_warnings``)


class VerdictItem(BaseModel):
    """A red, yellow or unchecked item of the evaluation: its zone, the sentence that
    says what, how much, against what and where, and the rule's source."""

    zone: Literal["green", "yellow", "red", "unchecked", "info"]
    text: str
    source: str


class HandShape(BaseModel):
    """A hand's envelope as the verdict judged it (``pliant.assembly.access``): its
    centre on the part [m], the best approach (unit), how far the forearm reaches out
    along it and the ring's radius round the part [m], the room left (negative: none
    fits) [m], what bounds it and the access check's zone."""

    grip: str
    centre: list[float]
    approach: list[float]
    reach: float
    ring: float
    clearance: float
    bound_by: str
    zone: Literal["green", "yellow", "red", "unchecked", "info"]


class WorkerShape(BaseModel):
    """The worker reaching a grip (``pliant.assembly.posture``): the stick figure's
    points [m] (feet, hip, shoulder, elbow, grip), the arm's side and the worst zone of
    its reach and posture checks."""

    grip: str
    chain: list[list[float]]
    side: Literal["right", "left"]
    zone: Literal["green", "yellow", "red", "unchecked", "info"]


class Verdict(BaseModel):
    """The A/D evaluation of the pose (``pliant.assembly.evaluate_pose``, the same rules
    as ``pliant evaluate``): whether it passes, in plain words, the operator it needs,
    the items to act on, and the hands and worker it judged (to draw)."""

    passes: bool
    headline: str
    operator: str | None
    zone: Literal["green", "yellow", "red", "unchecked", "info"]
    items: list[VerdictItem] = []
    hands: list[HandShape] = []
    worker: list[WorkerShape] = []


class FittedShape(BaseModel):
    """A flexible part already fitted, as this answer has it: its neutral line [m] and
    outer radius [m] (deformed where the part touches it, else at rest)."""

    name: str
    position: list[list[float]]
    radius: float


class ServerAccurate(_Message):
    """An accurate equilibrium (real forces): the shape, curvature and bending moment
    along s, what each condition applies (``loads``; for a grip held by position this is
    the force and moment the hand must give), contacts, interference, the tightest bend,
    the warnings a user must see, the solver's notes (how it got there) and the pose's
    A/D ``verdict``. ``error`` when there is none (the last good one stays shown)."""

    type: Literal["accurate"] = "accurate"
    index: int
    ok: bool
    error: str | None = None
    s: list[float] = []
    position: list[list[float]] = []
    curvature: list[float] = []
    bending_moment: list[float] = []
    loads: list[Load] = []
    contacts: list[Contact] = []
    interference: Interference | None = None
    fitted: list[FittedShape] = []
    branches: list[FittedShape] = []  # a harness's branches (their own tubes)
    min_bend_radius: float | None = None
    min_bend_radius_s: float | None = None
    allowed_bend_radius: float | None = None
    stable: bool | None = None
    smallest_eigenvalue: float | None = None  # [N m] the stability test's (None: not run)
    residual: float | None = None
    iterations: int = 0
    solve_seconds: float = 0.0
    warnings: list[str] = []
    notes: list[str] = []
    verdict: Verdict | None = None


class EquilibriumOption(BaseModel):
    """One equilibrium of the pose: its neutral line [m], potential and elastic energy
    [J], stability verdict (stable, neutral, unstable, unknown) and smallest eigenvalue
    [N m], which way it bows, its largest bending moment [N m] and how it was reached."""

    position: list[list[float]]
    potential_energy: float
    energy: float
    verdict: str
    smallest_eigenvalue: float | None = None
    bows: str
    max_moment: float
    notes: list[str] = []


class ServerEquilibria(_Message):
    """The equilibria of the pose of event ``index``, best first (stable and neutral
    by potential energy, then unstable); ``current`` says whether the grips are still
    where they were (only then can one be chosen). ``error`` when the search failed."""

    type: Literal["equilibria"] = "equilibria"
    index: int
    current: bool
    ok: bool
    error: str | None = None
    seconds: float = 0.0
    options: list[EquilibriumOption] = []


class PathPlay(BaseModel):
    """A scene's [path] for the page to play: the grip's pose at each step (at most
    ``PATH_STEPS`` of them, evenly taken, the last always)."""

    grip: str
    positions: list[list[float]]
    tangents: list[list[float]] | None = None


PATH_STEPS = 1000


class Port(BaseModel):
    """A scene's port: where an end goes [m] and the axis the part leaves it along."""

    name: str
    position: list[float]
    axis: list[float]
    note: str = ""


class ServerScene(_Message):
    """The scene: its name, the part (length, radius [m]), the obstacles as triangle
    meshes [m], the grips, the dimension (2D scenes lie in z = 0), the tolerance
    envelopes of a variation study when the server was given one (``pliant view
    --envelope``), the [path] to play and the ports with their axes."""

    type: Literal["scene"] = "scene"
    name: str
    file: str
    dimension: int
    part: dict[str, Any]
    obstacles: list[ObstacleMesh]
    grips: list[Grip]
    margin: float
    envelopes: list[ObstacleMesh] = []
    path: PathPlay | None = None
    ports: list[Port] = []


class ServerSaved(_Message):
    type: Literal["saved"] = "saved"
    name: str
    folder: str = ""  # where it was written


class ServerError(_Message):
    """What was wrong with the last message (or the solve it asked for); the session goes
    on."""

    type: Literal["error"] = "error"
    message: str
    field: str | None = None


class ProtocolError(Exception):
    """A message the server cannot take: ``field`` names where, the text says why."""

    def __init__(self, message: str, field: str | None = None) -> None:
        super().__init__(message)
        self.field = field


def parse(raw: str | bytes) -> ClientHello | ClientMove | ClientMode | ClientSolve \
        | ClientSave | ClientLoad | ClientEquilibria | ClientChoose:
    """A client message from its wire text, or ``ProtocolError`` saying what is wrong."""
    size = len(raw.encode() if isinstance(raw, str) else raw)
    if size > MAX_MESSAGE:
        raise ProtocolError(f"message of {size} bytes; the limit is {MAX_MESSAGE}", "message")
    try:
        data = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as err:
        raise ProtocolError(f"not JSON: {err}", "message") from None
    except RecursionError:
        raise ProtocolError("not a message: JSON nested too deeply", "message") from None
    if not isinstance(data, dict):
        raise ProtocolError("a message is a JSON object with 'v' and 'type'", "message")
    if data.get("v") != VERSION:
        raise ProtocolError(f"protocol version {data.get('v')!r}; this server speaks "
                            f"{VERSION}", "v")
    try:
        return _CLIENT.validate_python(data)
    except ValidationError as err:
        first = err.errors()[0]
        if first["type"] in ("union_tag_invalid", "union_tag_not_found"):
            raise ProtocolError(f"type: {data.get('type')!r} is not a message; the types "
                                f"are {', '.join(TYPES)}", "type") from None
        where = ".".join(str(p) for p in first["loc"][1:]) or "message"  # [0]: the type
        raise ProtocolError(f"{data['type']}.{where}: {first['msg']}", where) from None


SERVER_MESSAGES = (ServerScene, ServerFrame, ServerAccurate, ServerEquilibria, ServerSaved,
                   ServerError)
JAVASCRIPT = Path(__file__).with_name("static") / "protocol.js"


def javascript() -> str:
    """The page's side of this protocol (``static/protocol.js``), made from these models so
    the two cannot drift apart: the version, each message type with its fields, and
    ``message(type, fields)``, which the page sends through and which throws on a type or
    field the server does not take. ``python -m pliant.viewer.protocol`` writes it;
    ``tests/test_viewer.py`` checks the file is what this makes."""
    def fields(model: type[BaseModel]) -> list[str]:
        return [name for name in model.model_fields if name not in ("v", "type")]

    client = {_type_of(m): fields(m) for m in CLIENT_MESSAGES}
    server = {_type_of(m): fields(m) for m in SERVER_MESSAGES}
    return (
        "// Made by `python -m pliant.viewer.protocol` from pliant/viewer/protocol.py (the\n"
        "// pydantic models): do not edit. The wire protocol's version, the messages the\n"
        "// page may send (type: fields) and those the server answers with.\n"
        f"export const VERSION = {VERSION};\n"
        f"export const CLIENT = Object.freeze({json.dumps(client, indent=2)});\n"
        f"export const SERVER = Object.freeze({json.dumps(server, indent=2)});\n"
        "// A client message, checked against CLIENT: a type or field the server does not\n"
        "// take is the page's bug, thrown here and not sent.\n"
        "export function message(type, fields = {}) {\n"
        "  const known = CLIENT[type];\n"
        "  if (!known) throw new Error(`protocol: no client message '${type}'`);\n"
        "  for (const name of Object.keys(fields)) {\n"
        "    if (!known.includes(name)) {\n"
        "      throw new Error(`protocol: ${type} has no field '${name}'`);\n"
        "    }\n"
        "  }\n"
        "  return JSON.stringify({ v: VERSION, type, ...fields });\n"
        "}\n")


def dump(message: _Message) -> str:
    """The wire text of a server message (non-finite numbers as null: JSON has none)."""
    return json.dumps(finite(message.model_dump()), separators=(",", ":"))


if __name__ == "__main__":
    JAVASCRIPT.write_text(javascript(), encoding="utf-8")
    print(f"wrote {JAVASCRIPT}")
