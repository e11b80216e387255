"""Stage contracts: what a stage writes (:class:`Outputs`) and what it reads (:class:`Inputs`).

A stage owns its folder. Its ``Outputs`` subclass names every file in it (``LAYOUT``: key ->
:class:`File`, a path relative to the folder, possibly with ``{view}``-style fields) and gives the
loaders other stages, metrics, benchmarks and rules use; nobody else spells a file name of
another stage's folder. Loaders check dtype and shape and name the file when it is wrong.

A stage's ``Inputs`` subclass is a dataclass of upstream ``Outputs``, paths and scalars. Its
command-line flags derive from its fields (``masks_dir`` -> ``--masks-dir``), so one artifact has
one flag name in every stage. Field help comes from ``field(metadata={"help": ...})``.

Every stage's ``run(inputs, cfg) -> Outputs``.

    class EffectsOutputs(Outputs):
        LAYOUT = {"effects": File("effects.json", "per effect: detected, ...")}

    EffectsOutputs("results/demo/effects").path("effects")   # results/demo/effects/effects.json

``FOLDER`` says where the folder lies under the results root (``"{scene}/effects"``,
``"{scene}/{variant}/round{round}"``), so each file has one location. A stage module's ``Outputs``
that sets neither gets ``STAGE`` from its module (``anigs.stages.<name>``) and ``FOLDER`` from the
stage's scope (:func:`scope_folder`: ``{scene}/<name>``, ``{scene}/{variant}/<name>`` or ``<name>``). A stage whose files lie in
several folders lists its ``Outputs`` types in the module's ``OUTPUTS`` (:func:`outputs_of`); a
folder may hold several stages' files (``round{r}/``: render_clip, refine, update), but a file
belongs to exactly one ``Outputs``.

The library below the stages (metrics) reads two stages' folders without naming their modules: it
types them by the :class:`CaptureFiles` and :class:`MaskFiles` protocols here, which the capture and
masks stages' ``Outputs`` satisfy (``tests/core/test_layers.py`` checks both).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import string
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, Union

import numpy as np

from anigs.io import atomic_path
from anigs.registry import BY_NAME
from anigs.video import load_clip

if TYPE_CHECKING:
    from anigs.cameras import Camera
    from anigs.gaussians import Gaussians


@dataclass(frozen=True)
class File:
    """One file (or folder, ``name`` ending in ``/``) of a stage's output folder.

    ``name``: relative path, may hold ``str.format`` fields (``"{view}.png"``); ``doc``: what it
    holds, with dtype and shape for arrays; ``optional``: written only in some configurations."""

    name: str
    doc: str
    optional: bool = False

    @property
    def fields(self) -> tuple[str, ...]:
        """The format fields of ``name`` (``("view",)`` for ``"{view}.png"``)."""
        return tuple(f for _, f, _, _ in string.Formatter().parse(self.name) if f)


class Outputs:
    """A stage's output folder. Subclasses set ``LAYOUT`` (key -> :class:`File`) and add loaders."""

    LAYOUT: ClassVar[dict[str, File]] = {}
    STAGE: ClassVar[str] = ""   # the stage's name (anigs.stages.STAGES)
    FOLDER: ClassVar[str] = ""  # the folder under the results root, with {scene}/{variant}/{round} fields

    def __init_subclass__(cls, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        pkg, _, name = cls.__module__.rpartition(".")
        if pkg != "anigs.stages":
            return
        if "STAGE" not in cls.__dict__:
            cls.STAGE = name
        if not cls.FOLDER:  # neither set here nor inherited (RoundOutputs)
            cls.FOLDER = scope_folder(cls.STAGE)

    def __init__(self, root: str | Path):
        self.root = Path(root)

    def __fspath__(self) -> str:
        return str(self.root)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({str(self.root)!r})"

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and other.root == self.root  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash((type(self).__name__, self.root))

    @classmethod
    def at(cls, results: str | Path, **fields: Any):
        """The folder of these outputs under ``results`` (``FOLDER`` filled from ``fields``)."""
        if not cls.FOLDER:
            raise ValueError(f"{cls.__name__} has no FOLDER")
        return cls(Path(results) / cls.FOLDER.format(**fields))

    def path(self, key: str, **fields: Any) -> Path:
        """The path of file ``key`` (its format fields filled from ``fields``)."""
        try:
            f = self.LAYOUT[key]
        except KeyError:
            raise KeyError(f"{type(self).__name__} has no file {key!r}; files: {sorted(self.LAYOUT)}") from None
        missing = [k for k in f.fields if k not in fields]
        if missing:
            raise KeyError(f"{type(self).__name__}.path({key!r}) needs {missing} for {f.name!r}")
        return self.root / f.name.format(**fields)

    @classmethod
    def under(cls, results: str | Path, key: str | None = None, **fields: Any) -> str:
        """File ``key`` (None: the folder) under the results root: ``FOLDER`` and the ``LAYOUT`` name with
        ``fields`` filled in and the others left as ``{name}`` (a Snakemake rule's output pattern, or a
        path when every field is given)."""
        rel = cls.FOLDER if key is None else f"{cls.FOLDER}/{cls.LAYOUT[key].name}"
        return f"{results}/{rel}".rstrip("/").format_map(_Unfilled(fields))

    @classmethod
    def pattern(cls, key: str, root: str = "") -> str:
        """``root/name`` with the format fields left in (a Snakemake pattern when they are wildcards)."""
        name = cls.LAYOUT[key].name
        return f"{root.rstrip('/')}/{name}" if root else name

    def exists(self, key: str, **fields: Any) -> bool:
        return self.path(key, **fields).exists()

    # ---- checked loaders shared by the subclasses ----

    def json(self, key: str, **fields: Any) -> Any:
        """The JSON file ``key``; a missing or malformed file raises naming it and the stage."""
        p = self.path(key, **fields)
        try:
            return json.loads(p.read_text())
        except FileNotFoundError:
            raise FileNotFoundError(f"{p}: missing (run the {self.STAGE or 'upstream'} stage)") from None
        except ValueError as e:
            raise ValueError(f"{p}: not valid JSON ({e}); re-run the {self.STAGE or 'upstream'} stage") from None

    def array(self, key: str, dtype: str | None = None, shape: tuple[int | None, ...] | None = None,
              **fields: Any) -> np.ndarray:
        """The ``.npy`` file ``key``, checked: ``dtype`` a numpy kind (``"b"`` bool, ``"i"`` signed int,
        ``"f"`` float, ...) or kinds string, ``shape`` with None for any extent."""
        p = self.path(key, **fields)
        if not p.is_file():
            raise FileNotFoundError(f"{p}: missing (run the {self.STAGE or 'upstream'} stage)")
        a = np.load(p, allow_pickle=False)
        return check_array(a, str(p), dtype, shape)

    def clip(self, key: str, **fields: Any) -> tuple[np.ndarray, dict]:
        """(frames float32 [T,H,W,3], metadata) of the clip file ``key`` (:func:`anigs.video.load_clip`)."""
        p = self.path(key, **fields)
        if not p.is_file():
            raise FileNotFoundError(f"{p}: missing (run the {self.STAGE or 'upstream'} stage)")
        return load_clip(p)

    def save_array(self, key: str, a: np.ndarray, **fields: Any) -> Path:
        """Write the ``.npy`` file ``key`` atomically (temp + rename); returns its path."""
        p = self.path(key, **fields)
        with atomic_path(p) as tmp, open(tmp, "wb") as fh:
            np.save(fh, a)
        return p


class _Unfilled(dict):
    """Format fields: a field that is not given stays ``{name}`` (a Snakemake wildcard)."""

    def __missing__(self, key: str) -> str:
        return f"{{{key}}}"


def scope_folder(stage: str) -> str:
    """The default folder of a stage's files under the results root, from its scope in the registry:
    ``{scene}/<name>`` (scene), ``{scene}/{variant}/<name>`` (variant), ``<name>`` (global)."""
    return {"scene": "{scene}/", "variant": "{scene}/{variant}/", "global": ""}[BY_NAME[stage].scope] + stage


class RoundOutputs(Outputs):
    """A round's folder (``round{r}/``), which several stages write into: render_clip (``render/``),
    refine (``target/``), update (the model) and round (both of the first)."""

    FOLDER = "{scene}/{variant}/round{round}"


class CaptureFiles(Protocol):
    """The capture stage's folder as the metrics read it: the synthetic scene's ground truth (``gt/``).
    ``n``: the expected number of ground-truth Gaussians (None: any); a wrong dtype or shape raises."""

    def gt_cameras(self) -> list[Camera]:
        """The ground-truth cameras (``gt/cameras.json``)."""
        ...

    def gt_gaussians(self) -> Gaussians:
        """The ground-truth Gaussians, N of them (``gt/gaussians.ply``)."""
        ...

    def gt_labels(self, n: int | None = None) -> np.ndarray:
        """int [N]: the semantic label of each ground-truth Gaussian."""
        ...

    def gt_anchors(self, n: int | None = None) -> np.ndarray:
        """float32 [N,3]: the sway anchor of each ground-truth Gaussian."""
        ...

    def gt_motion(self) -> dict:
        """``gt/motion.json``: ``params`` (the motion parameters) and the label/effect tables (``labels``:
        label id as a string -> label name)."""
        ...


class MaskFiles(Protocol):
    """The masks stage's folder as the metrics read it: a dynamic mask per view, maybe split by effect."""

    root: Path  # the folder (named in messages)

    def has_view_mask(self, view: str) -> bool:
        """Whether ``view`` has a dynamic mask."""
        ...

    def view_mask(self, view: str) -> np.ndarray:
        """float32 [H,W] in [0, 1]: the dynamic mask of ``view``."""
        ...

    def effect_masks(self, view: str) -> dict[str, np.ndarray]:
        """effect -> float32 [H,W] in [0, 1]: the part of ``view``'s mask each effect moves (empty: one effect)."""
        ...


def outputs_of(module: types.ModuleType) -> tuple[type[Outputs], ...]:
    """The ``Outputs`` types of a stage module: its ``OUTPUTS`` when it writes into several folders,
    else its ``Outputs`` alone; ``()`` for a stage that writes nothing of its own."""
    if hasattr(module, "OUTPUTS"):
        return tuple(module.OUTPUTS)
    return (module.Outputs,) if hasattr(module, "Outputs") else ()


def check_array(a: np.ndarray, where: str, dtype: str | None = None,
                shape: tuple[int | None, ...] | None = None) -> np.ndarray:
    """``a`` unchanged when its dtype kind is in ``dtype`` and its shape matches ``shape`` (None: any
    extent); otherwise a ValueError naming ``where``, the expected and the found dtype/shape."""
    if dtype is not None and a.dtype.kind not in dtype:
        raise ValueError(f"{where}: dtype {a.dtype} where kind {dtype!r} is expected")
    if shape is not None and (a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape))):
        want = "[" + ", ".join("*" if s is None else str(s) for s in shape) + "]"
        raise ValueError(f"{where}: shape {list(a.shape)} where {want} is expected (re-run the stage that wrote it)")
    return a


# ---- inputs: flags derived from fields ----

def upstream(outputs: type[Outputs], key: str, what: str, **kw: Any) -> Any:
    """An ``Inputs`` field that takes one file of an upstream stage (a path), its help naming the file:
    ``upstream(StaticOutputs, "canonical", "canonical 3DGS PLY")`` -> "canonical 3DGS PLY (static/canonical.ply)".
    ``kw``: more ``dataclasses.field`` arguments (``default``)."""
    name = f"{Path(outputs.FOLDER).name}/{outputs.LAYOUT[key].name}".rstrip("/")
    return dataclasses.field(metadata={"help": f"{what} ({name})"}, **kw)


def output_folder(outputs: type[Outputs], what: str = "output folder") -> Any:
    """The ``--out`` field of a stage that writes ``outputs``, its help listing the files it always writes."""
    names = ", ".join(f.name.rstrip("/") for f in outputs.LAYOUT.values() if not f.optional and not f.fields)
    return dataclasses.field(metadata={"help": f"{what} ({names})" if names else what})


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _unwrap_optional(tp: Any) -> tuple[Any, bool]:
    """(T, True) for ``T | None`` / ``Optional[T]``, else (tp, False)."""
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0], True
    return tp, False


@dataclass
class Inputs:
    """Base of a stage's inputs. Subclasses are dataclasses whose fields are upstream
    :class:`Outputs`, ``Path``, ``str``, ``int``, ``float``, ``bool`` or ``list[str]`` (each maybe
    ``| None``). Fields without a default are required flags."""

    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser, optional: tuple[str, ...] = ()) -> None:
        """One flag per field: ``--field-name`` (an ``Outputs`` field takes its folder). ``optional``: fields
        without a default whose flags may still be left out (a mode of the command that does not read them)."""
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            tp, _ = _unwrap_optional(hints[f.name])
            required = (f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
                        and f.name not in optional)
            default = None if f.default is dataclasses.MISSING else f.default
            help_ = f.metadata.get("help", "")
            if isinstance(tp, type) and issubclass(tp, Outputs):
                help_ = help_ or f"the {tp.STAGE} stage's folder"
                p.add_argument(_flag(f.name), dest=f.name, required=required, metavar="DIR", help=help_)
            elif tp is bool:
                p.add_argument(_flag(f.name), dest=f.name, action="store_true", help=help_)
            elif typing.get_origin(tp) is list:
                p.add_argument(_flag(f.name), dest=f.name, nargs="*", required=required, default=default, help=help_)
            else:
                conv = tp if tp in (int, float) else str
                p.add_argument(_flag(f.name), dest=f.name, type=conv, required=required, default=default, help=help_)

    @classmethod
    def from_args(cls, args: argparse.Namespace):
        """The inputs from parsed flags (paths as ``Path``, folders as their ``Outputs``)."""
        hints = typing.get_type_hints(cls)
        kw: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            if not hasattr(args, f.name):
                continue
            v = getattr(args, f.name)
            tp, _ = _unwrap_optional(hints[f.name])
            if v is not None and isinstance(tp, type) and (issubclass(tp, Outputs) or tp is Path):
                v = tp(v)
            kw[f.name] = v
        return cls(**kw)

    def argv(self) -> list[str]:
        """The flags that give these inputs back through :meth:`from_args` (for composed commands)."""
        out: list[str] = []
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if v is None or v is False:
                continue
            if v is True:
                out.append(_flag(f.name))
            elif isinstance(v, (list, tuple)):
                out += [_flag(f.name), *map(str, v)]
            else:
                out += [_flag(f.name), str(v.root if isinstance(v, Outputs) else v)]
        return out
