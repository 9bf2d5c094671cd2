"""Declared input: the toolkit's files as pydantic models, and the one line a bad value gives.

Files are read by `read_toml` (or `read_text`) and checked by `validate`: ``robot.toml``
(`Description`), a ``[hydraulics]`` table (`Hydraulics`), a task file (`TaskFile`); the map
families of `redundancy.study.families` and the ``[actuators.<name>]`` tables of
`redundancy.model.transmissions` are built from the pieces here. Every model refuses unknown
keys, reads numbers strictly and finite, and declares each quantity's unit, range and likely
unit mistakes (`quantity`). `message` turns a `pydantic.ValidationError` into one line, read
against the model's JSON schema: the file, the table and key, the value given as the file
writes it (`toml`, at most `EXCERPT` characters of it) and what it must be.
"""

from __future__ import annotations

import functools
import json
import os
import re
import stat
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal, TypeVar, Union

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    model_validator,
)
from pydantic_core import PydanticCustomError

from redundancy.errors import InvalidInputError
from redundancy.model.values import MAX_ACCELERATION, MAX_PAYLOAD, MAX_SPEED

MAX_BYTES = 1 << 24  # 16 MiB: far beyond any description, task, circuit, family or recorded path
EXCERPT = 40  # characters of a user's value a message quotes at most
BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")  # a TOML key written without quotes
MAX_OFFSET = 100.0  # m: a point on a link, a length or a stroke; beyond is surely mm given as m
MM_PER_S = "did you give mm/s? 1 m/s = 1000 mm/s"
DECLARED = "declared"  # the error type of the rules declared here, whose text is the message
Model = TypeVar("Model", bound=BaseModel)


def read_text(path: Path, what: str, error: type[Exception] = InvalidInputError) -> str:
    """The UTF-8 text (a byte-order mark allowed) of the regular file ``path`` (a ``what``,
    e.g. "task file") of at most `MAX_BYTES`, or one ``error`` line saying why not."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            raise error(f"{path}: not a {what}: not a regular file")
        with path.open("rb") as file:
            data = file.read(MAX_BYTES + 1)
    except OSError as failure:
        raise error(f"cannot read {what} {path}: {failure.strerror}") from None
    if len(data) > MAX_BYTES:
        raise error(f"{path}: not a {what}: larger than {MAX_BYTES >> 20} MiB")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise error(f"{path}: not a {what}: not UTF-8 text") from None


def read_toml(path: Path, what: str, error: type[Exception] = InvalidInputError) -> dict:
    """The tables of the TOML file ``path`` (a ``what``), or one ``error`` line."""
    try:
        return tomllib.loads(read_text(path, what, error))
    except tomllib.TOMLDecodeError as failure:
        raise error(f"{path}: not valid TOML: {failure}") from None


def excerpt(value: object, written: Callable[[object], str] = repr) -> str:
    """``value`` as ``written`` writes it (its repr; `toml` for a file's value), cut to
    `EXCERPT` characters: a message never echoes a whole file."""
    text = written(value)
    return text if len(text) <= EXCERPT else text[: EXCERPT - 3] + "..."


def toml(value: object) -> str:
    """``value`` read from a TOML file as the file writes it: true, "text", [1.0, 2], {a = 1}."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # a TOML basic string's escapes are JSON's
    if isinstance(value, list):
        return f"[{', '.join(map(toml, value))}]"
    if isinstance(value, dict):
        pairs = (
            f"{k if BARE_KEY.fullmatch(str(k)) else toml(k)} = {toml(v)}" for k, v in value.items()
        )
        return f"{{{', '.join(pairs)}}}"
    return str(value)  # a number (inf, nan), a date or a time


class Table(BaseModel):
    """A table of a declared file: unknown keys refused, numbers strict and finite. ``entries``
    says what its keys are called in messages."""

    model_config = ConfigDict(
        extra="forbid",
        strict=True,
        allow_inf_nan=False,
        frozen=True,
        json_schema_extra=lambda schema, cls: schema.update(entries=cls.entries),
    )
    entries: ClassVar[str] = "keys"


def quantity(
    meaning: str,
    unit: str,
    lower: float,
    upper: float,
    default: Any = ...,
    *,
    above: str = "",
    below: str = "",
    open_lower: bool = False,
) -> Any:
    """A number's field: what it means, its unit, its range [lower, upper] (lower excluded
    where ``open_lower``) and the likely mistakes of a value ``above`` or ``below`` it."""
    return Field(
        default,
        description=f"{meaning}, {unit}",
        json_schema_extra={"above": above, "below": below},
        gt=lower if open_lower else None,
        ge=None if open_lower else lower,
        le=upper,
    )


def bar(meaning: str, lower: float = 1.0, default: Any = ...) -> Any:
    """A pressure in bar, within [``lower``, 1000]."""
    return quantity(
        meaning,
        "bar",
        lower,
        1000.0,
        default,
        above="did you give psi or Pa? 1 bar = 14.5 psi = 1e5 Pa",
        below="did you give MPa? 1 MPa = 10 bar" if lower > 0 else "",
    )


def _distinct(names: list[str]) -> list[str]:
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise PydanticCustomError(
            DECLARED, f"names {', '.join(map(toml, repeated))} more than once; give each once"
        )
    return names


Names = Annotated[list[str], AfterValidator(_distinct)]  # names, each given once


def either(table: Any, other: Any) -> Any:
    """A key that takes a TOML table (``table``) or another form (``other``); its errors are
    those of the form given."""
    return Annotated[
        Union[Annotated[table, Tag("table")], Annotated[other, Tag("other")]],  # noqa: UP007
        Discriminator(lambda value: "table" if isinstance(value, dict) else "other"),
    ]


def _within_offset(xyz: list[float]) -> list[float]:
    far = [c for c in xyz if abs(c) > MAX_OFFSET]
    if far:
        raise PydanticCustomError(
            DECLARED,
            f"must be within ±{MAX_OFFSET:g} m of the link's frame: {far[0]:g} m is beyond; "
            "did you give mm? 1 m = 1000 mm",
        )
    return xyz


Xyz = Annotated[
    list[float],
    Field(min_length=3, max_length=3, description="x, y, z in m, in the link's frame"),
    AfterValidator(_within_offset),
]


def _axes(axes: str) -> str:
    if not axes or any(a not in "xyz" for a in axes) or len(set(axes)) != len(axes):
        raise PydanticCustomError(DECLARED, "must be distinct letters among 'x', 'y', 'z'")
    return axes


Axes = Annotated[
    str, AfterValidator(_axes), Field(description="world axes of the task, e.g. 'xz'")
]  # the task's axes: the tool position's world components


class PointOnLink(Table):
    """A point fixed on a link: ``{link = "...", xyz = [x, y, z]}``, m in the link's frame."""

    link: str = Field(description="a link of the URDF")
    xyz: Xyz


class ArmOnLink(PointOnLink):
    """A point fixed on a link and a length from it, m: ``{link, xyz, length}``."""

    length: float = Field(gt=0.0, le=MAX_OFFSET, description="m")


class Description(Table):
    """A ``robot.toml`` (schema in `redundancy.model.loading.load_robot`): the tool is a link
    (``tool_frame``) or a point on a link (``tool``), one of them."""

    urdf: str = Field(description="the URDF, beside this file or package://")
    tool_frame: str | None = Field(
        description="the tool's link (None: the last); or tool = {link = ..., xyz = [...]}"
    )
    tool: PointOnLink | None = Field(None, description="the tool point")
    task_axes: Axes
    locked_joints: either(dict[str, float], list[str]) = Field(  # type: ignore[valid-type]
        [],
        description="joints fixed, at their neutral value or at one given in rad or m",
        json_schema_extra={"shape": "a list of names, or a table {joint = value}"},
    )
    payload: float = quantity("the point mass at the tool", "kg", 0.0, MAX_PAYLOAD, 0.0)
    task: str | None = Field(None, description="the robot's task file")
    actuators: dict[str, dict[str, Any]] = Field({}, description="[actuators.<name>] tables")
    hydraulics: dict[str, Any] | None = Field(None, description="the [hydraulics] table")

    @model_validator(mode="before")
    @classmethod
    def _one_tool(cls, data: Any) -> Any:
        if isinstance(data, dict) and "tool" in data:
            if "tool_frame" in data:
                raise PydanticCustomError(
                    DECLARED,
                    "tool_frame and tool are both given; give one: tool_frame = a link, or "
                    "tool = {link = ..., xyz = [...]}, a point on a link",
                )
            return {**data, "tool_frame": None}
        return data


class Overrides(Table):
    """What `redundancy.model.loading.load_robot` takes besides the description, checked as
    ``robot.toml``'s keys (None: the description's)."""

    payload: float | None = quantity("the point mass at the tool", "kg", 0.0, MAX_PAYLOAD, None)
    task_axes: Axes | None = None


class CylinderTable(Table):
    """A cylinder's ``[hydraulics.cylinders.<actuator>]`` table (or its URDF ``<cylinder>``)."""

    bore: float = quantity("bore D", "mm", 5.0, 1000.0, below="did you give m? 1 m = 1000 mm")
    rod: float = quantity("rod d", "mm", 0.0, 1000.0)
    # a cylinder slower than a millimetre per second, or accelerating slower than one per s², is
    # no machine's: such a value is a slip of the exponent
    max_speed: float = quantity("maximum speed", "m/s", 1e-3, 10.0, above=MM_PER_S)
    max_acceleration: float = quantity(
        "maximum acceleration",
        "m/s²",
        1e-3,
        100.0,
        above="did you give mm/s²? 1 m/s² = 1000 mm/s²",
    )

    @model_validator(mode="after")
    def _rod_inside(self) -> CylinderTable:
        if not self.rod < self.bore:
            raise PydanticCustomError(
                DECLARED,
                f"needs 0 ≤ rod < bore; got bore = {self.bore:g} mm, rod = {self.rod:g} mm",
            )
        return self


class Hydraulics(Table):
    """A machine's ``[hydraulics]`` table: its supply, pressures (bar), pump flow (L/min) and
    cylinders by actuator name; schema in docs/hydraulics.md."""

    supply: Literal["LS", "CP"] = Field(description="the machine's supply")
    ls_margin: float = bar("LS margin Δp_LS")
    cp_pressure: float = bar("CP supply pressure p_S")
    relief: float = bar("relief pressure")
    pump_flow: float = quantity(
        "pump's maximum flow",
        "L/min",
        0.1,
        10_000.0,
        below="did you give m³/s? 1 m³/s = 60,000 L/min",
        above="did you give mL/min? 1 L/min = 1000 mL/min",
    )
    tank: float = bar("tank pressure p_T", lower=0.0)
    cylinders: dict[str, CylinderTable] = {}

    @model_validator(mode="after")
    def _pressures_ordered(self) -> Hydraulics:
        if not self.tank < self.cp_pressure <= self.relief or not self.ls_margin < (
            self.relief - self.tank
        ):
            raise PydanticCustomError(
                DECLARED,
                f"needs tank < cp_pressure ≤ relief and ls_margin < relief − tank; got tank = "
                f"{self.tank:g}, cp_pressure = {self.cp_pressure:g}, relief = {self.relief:g}, "
                f"ls_margin = {self.ls_margin:g} bar",
            )
        return self


class Timing(Table):
    """How fast a task file's segments are travelled (each segment's table may override it)."""

    speed: float | None = quantity(
        "the tool's speed", "m/s", 0.0, MAX_SPEED, None, open_lower=True, above=MM_PER_S
    )
    profile: Literal["constant", "trapezoidal"] | None = None
    acceleration: float | None = quantity(
        "the trapezoidal profile's maximum",
        "m/s²",
        0.0,
        MAX_ACCELERATION,
        None,
        open_lower=True,
    )


class SegmentTable(Timing):
    """One segment of a task file given as a table (`redundancy.planning.tasks`)."""

    start: str | None = Field(None, alias="from", description="a point's name")
    to: str | None = Field(None, description="a point's name")
    via: str | None = Field(None, description="a point's name")
    centre: str | None = Field(None, description="a point's name")
    center: str | None = Field(None, description="a point's name")
    direction: Literal["ccw", "cw"] | None = None
    csv: str | None = Field(None, description="a CSV file of points, beside the task file")
    name: str | None = None


class TaskFile(Timing):
    """A task file (read by `redundancy.planning.tasks.WorkCycle.from_toml`; its keys are listed
    in docs/machines.md, under "Checking a new machine")."""

    name: str | None = None
    tool_angle: bool = False
    held: Names | None = Field(
        None, description="the actuators the improved search holds; leave it out for the default"
    )
    segments: list[either(SegmentTable, str)] = Field(  # type: ignore[valid-type]
        [],
        json_schema_extra={
            "shape": "a list of '<from>-<to>' names or segment tables, e.g. "
            'segments = ["1-2", { from = "2", to = "3", via = "4" }]'
        },
    )
    points: dict[str, list[float]] | None = Field(None, description="name = [coordinates]")


def validate(
    model: type[Model],
    data: object,
    source: str,
    table: str = "",
    error: type[Exception] = InvalidInputError,
    entries: str = "",
) -> Model:
    """``data`` read as ``model``, or one ``error`` line (`message`) naming ``source`` (the
    file), the ``table`` ``data`` is (dotted, "" for the whole file) and the key; unknown keys
    are called ``entries`` (the model's own word by default)."""
    try:
        return model.model_validate(data)
    except ValidationError as failure:
        raise error(message(failure, model, data, source, table, entries)) from None


def message(
    failure: ValidationError,
    model: type[BaseModel],
    data: object,
    source: str,
    table: str = "",
    entries: str = "",
) -> str:
    """The one line of ``failure``'s first error (an unknown key first: likely one misspelt),
    read against ``model``'s JSON schema: the file, the table and key, the value (an excerpt),
    what it must be (its shape, range and likely unit mistake) and what it means."""
    errors = failure.errors(include_url=False)
    first = ([e for e in errors if e["type"] == "extra_forbidden"] or errors)[0]
    kind, loc = first["type"], tuple(first["loc"])
    if kind in ("extra_forbidden", "missing"):
        path, forms, _ = _walk(model, loc[:-1])
        keys = [e["loc"][-1] for e in errors if e["type"] == kind and e["loc"][:-1] == loc[:-1]]
        if kind == "missing":
            said = f"missing key {keys[0]!r}" if len(keys) == 1 else f"missing keys {keys}"
        else:
            known = entries or forms[0].get("entries", "keys")
            said = f"unknown {known} {sorted(keys)}; {known}: {', '.join(forms[0]['properties'])}"
        return f"{_place(source, table, path)}: {said}"
    path, forms, exact = _walk(model, loc)
    if not path or (kind == DECLARED and _is_table(forms)):  # a rule across a table's keys
        said = (
            f": {first['msg']}" if kind == DECLARED else f" = {excerpt(data, toml)} must be a table"
        )
        return _place(source, table, path) + said
    value = excerpt(_get(data, path), toml)
    where = f"{_place(source, table, path[:-1], keyed=True)}{path[-1]} = {value}"
    return f"{where} {_problem(first, forms, exact)}"


_RANGE = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")
_TAGS = ("table", "other")  # the forms of `either`, as they appear in an error's location
_WORDS = {
    "number": "a finite number",
    "integer": "a whole number",
    "string": "a string",
    "boolean": "true or false",
}


def _problem(error: Any, forms: list[dict], exact: bool) -> str:
    """What a value of ``forms`` must be: a declared rule's words, a range with the likely unit
    mistake, or a shape; and what it means. ``exact``: the error is the value's own, not one of
    its items'."""
    form = forms[0]
    meaning = f" ({form['description']})" if form.get("description") else ""
    if error["type"] == DECLARED:
        return f"{error['msg']}{meaning}"
    empty = error["type"] in ("too_short", "string_too_short") and not len(error["input"])
    if exact and empty:  # an empty list or text where one is needed
        return f"must not be empty: {' or '.join(dict.fromkeys(map(_shape, forms)))}{meaning}"
    lower, upper = form.get("minimum", form.get("exclusiveMinimum")), form.get("maximum")
    if not (exact and error["type"] in _RANGE and None not in (lower, upper)):
        return f"must be {' or '.join(dict.fromkeys(map(_shape, forms)))}{meaning}"
    whole = "a whole number " if form["type"] == "integer" else ""
    low = "(" if "exclusiveMinimum" in form else "["
    hint = form.get("below" if "greater" in error["type"] else "above")
    return f"must be {whole}within {low}{lower:g}, {upper:g}]{meaning}" + (
        f"; {hint}" if hint else ""
    )


def _shape(form: dict) -> str:
    """What a value of the JSON-schema ``form`` is, in words."""
    if "shape" in form:
        return str(form["shape"])
    if "enum" in form:
        return "one of " + ", ".join(map(toml, form["enum"]))
    if form.get("type") == "array":
        item = form.get("items", {}).get("type")
        return "a list of " + {"string": "names", "number": "finite numbers"}.get(item, "values")
    return _WORDS.get(form.get("type", ""), "a table")


def _place(source: str, table: str, path: list, keyed: bool = False) -> str:
    """Where a key lies: the file and, unless the file's top level, its table."""
    parts = [table] if table else []
    for part in path:
        if not isinstance(part, int) and not re.fullmatch(r"[A-Za-z0-9_-]+", str(part)):
            part = toml(str(part))  # a key TOML writes quoted: "lift-cyl.1"
        parts.append(f"[{part}]" if isinstance(part, int) else f".{part}" if parts else part)
    name = "".join(parts)
    where = f"[{name}]" if name and "[" not in name else name
    if keyed:
        return f"{source}: {where} " if where else f"{source}: "
    return f"{source}: {where}" if where else source


def _get(data: object, path: list) -> object:
    for part in path:
        try:
            data = data[part]  # type: ignore[index]
        except (KeyError, IndexError, TypeError):
            return None
    return data


@functools.cache
def _schema(model: type[BaseModel]) -> dict:
    return model.model_json_schema()


def _forms(node: dict, defs: dict) -> list[dict]:
    """The forms a JSON-schema ``node`` allows (its reference followed, its union's members
    but null), each with the node's own description and hints."""
    own = {k: v for k, v in node.items() if k not in ("$ref", "anyOf", "oneOf")}
    if "$ref" in node:
        target = defs[node["$ref"].rsplit("/", 1)[1]]
        inner = [{k: v for k, v in target.items() if k != "description"}]
    else:
        members = node.get("anyOf", []) + node.get("oneOf", [])
        inner = [f for m in members if m.get("type") != "null" for f in _forms(m, defs)]
    return [{**form, **own} for form in inner] or [node]


def _is_table(forms: list[dict]) -> bool:
    return all(form.get("type") == "object" for form in forms)


def _walk(model: type[BaseModel], loc: tuple) -> tuple[list, list[dict], bool]:
    """Follow ``loc`` through ``model``'s JSON schema to the deepest named key (a field, a
    table's key, or a list's item that is a table): its path, its forms, and whether the
    error is the value's own (not one of its items')."""
    schema = _schema(model)
    steps: list[tuple[object, list[dict]]] = [((), [schema])]
    for part in loc:
        forms = steps[-1][1]
        if part in _TAGS:  # the form the value took: narrow the key's forms to it
            steps[-1] = (steps[-1][0], [f for f in forms if _is_table([f]) == (part == "table")])
            continue
        nodes = (f.get("items") if isinstance(part, int) else _key(f, part) for f in forms)
        found = next((node for node in nodes if node), None)
        if found is None:
            break
        steps.append((part, _forms(found, schema.get("$defs", {}))))
    exact = len(steps) - 1 == len([part for part in loc if part not in _TAGS])
    while len(steps) > 1 and isinstance(steps[-1][0], int) and not _is_table(steps[-1][1]):
        steps.pop()
    return [step[0] for step in steps[1:]], steps[-1][1], exact


def _key(form: dict, key: object) -> dict | None:
    """The node of ``key`` in the table ``form``: a field, or a value of a free table."""
    free = form.get("additionalProperties")
    return form.get("properties", {}).get(key, free if isinstance(free, dict) else None)
