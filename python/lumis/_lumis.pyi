"""Type stubs of the lumis extension module (re-exported by the ``lumis`` package)."""

from collections.abc import Callable, Iterator, Mapping, Sequence
from os import PathLike
from typing import Any, Optional, Union

import numpy as np
import numpy.typing as npt

StrPath = Union[str, PathLike[str]]

class LumisError(Exception):
    """Base class of every error lumis raises (an internal error, a panic caught before it
    reached Python, is raised as this class itself)."""

class SceneError(LumisError):
    """A problem with a scene or a file it refers to.

    ``str(error)`` is the CLI's message, ``file[:line:col]: message``.
    """

    file: str
    """The file the problem is in: the scene file (``<dict>`` for `load_dict`) or an asset."""
    line: Optional[int]
    """1-based line of the problem in a text file, if it has a position."""
    column: Optional[int]
    """1-based column, with `line`."""
    message: str
    """The message without the file and position."""

class PluginError(LumisError):
    """An unknown plugin, or parameters a plugin refuses, given to `Scene.render`
    (``scene.ron: integrator: unknown integrator plugin `x` ...``)."""

class RenderError(LumisError):
    """The render could not run (its threads could not start)."""

class OutputError(LumisError):
    """An output file could not be written."""

    path: str
    """The file that could not be written."""

class PassReport:
    """What a render in passes reports after each pass: to `Scene.render`'s ``on_pass``, and in
    `RenderResult.passes`."""

    @property
    def index(self) -> int:
        """The pass's index, 0 for the first."""
    @property
    def samples(self) -> int:
        """Camera samples per pixel after the pass."""
    @property
    def time(self) -> float:
        """Seconds since the render's first pass started."""
    @property
    def error(self) -> Optional[float]:
        """The image's estimated error after the pass (None if the render estimates none: a
        render in passes of odd sizes)."""
    @property
    def interval(self) -> Optional[tuple[float, float]]:
        """(low, high): holds the image's error with probability `confidence`."""
    @property
    def metric(self) -> Optional[str]:
        """The error's metric: ``"relmse"`` or ``"mse"``."""
    @property
    def confidence(self) -> Optional[float]:
        """The interval's confidence."""
    @property
    def last(self) -> bool:
        """Whether the pass was planned as the render's last."""

class RenderResult:
    """A finished render: every layer as a read-only ``numpy.float32`` array of shape
    (height, width, channels) by name, the render's statistics (those of the CLI's summary line)
    and `write`, which writes the CLI's files.

    Layers: ``"color"`` (channels R, G, B: linear Rec. 709 radiance) and every AOV the
    integrator declares, e.g. ``"alpha"`` (``combined``, ``light0``...), ``"alpha_color"``,
    ``"sampling_variance"`` (``Y``), ``"samples"`` (``bsdf``, ``light``); see
    docs/integrators.md. The height and width are those of the film's crop window, if any.
    """

    def __getitem__(self, name: str) -> npt.NDArray[np.float32]:
        """The layer called `name`; raises KeyError (listing the layers) if there is none."""
    def __contains__(self, name: str) -> bool: ...
    def __len__(self) -> int: ...
    def __iter__(self) -> Iterator[str]:
        """The layer names, colour first."""
    def keys(self) -> list[str]:
        """The layer names, colour first."""
    @property
    def layers(self) -> dict[str, npt.NDArray[np.float32]]:
        """Every layer by name, colour first."""
    @property
    def channels(self) -> dict[str, list[str]]:
        """Every layer's channel names, e.g. ``{"color": ["R", "G", "B"], "alpha": ["combined", "light0"]}``."""
    @property
    def time(self) -> float:
        """Render time (wall clock) in seconds, without scene loading and integrator preprocessing."""
    @property
    def camera_samples(self) -> int:
        """Camera samples shaded (pixels × spp)."""
    @property
    def rays(self) -> int:
        """Ray queries (closest hit and occlusion)."""
    @property
    def threads(self) -> int:
        """Worker threads used."""
    @property
    def pixels(self) -> int:
        """Pixels rendered (the window's width × height)."""
    @property
    def tiles(self) -> int:
        """16 × 16 tiles rendered."""
    @property
    def samples_per_second(self) -> float:
        """Camera samples per second of render time."""
    @property
    def rays_per_second(self) -> float:
        """Ray queries per second of render time."""
    @property
    def spp(self) -> int:
        """Camera samples per pixel."""
    @property
    def seed(self) -> int:
        """The render's seed."""
    @property
    def passes(self) -> list[PassReport]:
        """A render in passes: each pass's report, in order (empty for a plain render)."""
    @property
    def error(self) -> Optional[float]:
        """The image's estimated error (a render in passes; else None): see
        docs/integrators.md, "Passes", for what it estimates."""
    @property
    def error_interval(self) -> Optional[tuple[float, float]]:
        """(low, high): holds the image's error with the render's confidence."""
    @property
    def stopped(self) -> Optional[str]:
        """Why a render in passes ended: ``"target"`` (its last pass was sized to reach the
        target), ``"max-spp"``, ``"max-time"``, ``"time"``, ``"samples"``; None for a plain
        render or one stopped by ``on_pass``."""
    @property
    def partial(self) -> bool:
        """Whether the image is partial: a render in passes stopped by ``on_pass`` before the
        pass planned as its last (its passes then weighted to sum to one: consistent, not
        unbiased)."""
    @property
    def integrator(self) -> dict[str, Any]:
        """The integrator that rendered, as in a scene: ``{"type": "alpha", "samples": 64, ...}``."""
    @property
    def metadata(self) -> list[tuple[str, str]]:
        """The ``lumis`` metadata stored in the EXR header, as (key, value) pairs."""
    def write(self, path: StrPath, exposure: Optional[float] = None) -> list[str]:
        """Writes the files ``lumis render -o path`` writes, bit for bit: the EXR at `path`
        (colour, every AOV layer, the metadata), the sRGB preview ``<path>.png`` scaled by
        2^`exposure` (default: the film's ``exposure``) and ``<path>.<aov>.png`` for AOVs with a
        preview (the α map). Each file is written atomically. `path` must end in ``.exr``.

        Returns the paths written, the EXR first. Raises `OutputError`.
        """

class Scene:
    """A built scene (camera, shapes, BVH, BSDFs, lights), ready to render any number of times.

    Renders of one scene run one after the other (each sets the scene's spp and seed);
    different scenes may render at once from different Python threads.
    """

    @property
    def name(self) -> str:
        """The scene as named when loaded: its path as given, or ``<dict>``."""
    @property
    def load_time(self) -> float:
        """Seconds spent reading, parsing and building the scene."""
    @property
    def size(self) -> tuple[int, int]:
        """The full film's (width, height)."""
    @property
    def spp(self) -> int:
        """Camera samples per pixel the scene asks for (``sampler.spp``)."""
    @property
    def seed(self) -> int:
        """The scene's seed (``sampler.seed``)."""
    @property
    def integrator(self) -> dict[str, Any]:
        """The scene's integrator, as in the scene: ``{"type": "balance", "samples": 64}``."""
    def render(
        self,
        integrator: Optional[str] = None,
        spp: Optional[int] = None,
        seed: Optional[int] = None,
        threads: Optional[int] = None,
        target_error: Optional[float] = None,
        time: Optional[float] = None,
        passes: Optional[int] = None,
        metric: Optional[str] = None,
        confidence: Optional[float] = None,
        max_spp: Optional[int] = None,
        max_time: Optional[float] = None,
        on_pass: Optional[Callable[[PassReport], Optional[bool]]] = None,
        budgets: Optional[str] = None,
        **params: Any,
    ) -> RenderResult:
        """Renders the scene and returns its layers as numpy arrays.

        A render to a target error, in a time or in passes (``lumis render --target-error``,
        ``--time``, ``--passes``) runs in passes, the image's error estimated after each::

            result = scene.render(target_error=0.01, on_pass=lambda p: print(p))
            result.error, result.error_interval, result.samples_per_second

        Args:
            integrator: the integrator plugin's name (``"balance"``, ``"alpha"``, ...; see
                `plugins`); default the scene's. Like ``--set integrator.type=NAME``, the scene's
                integrator parameters are kept.
            spp: camera samples per pixel; default the scene's ``sampler.spp``.
            seed: the random seed; default the scene's ``sampler.seed``. A render is a
                function of the scene, spp and seed alone: the same for any number of threads.
            threads: worker threads; default one per core.
            target_error: render in passes until the image's error (`metric`) is below this
                with the `confidence`, or a cap (`max_spp`, default 4096; `max_time`, seconds).
            time: render in passes the best image this many seconds allow (`max_spp` caps it).
            passes: render `spp` samples in this many passes (the same image as one pass).
            metric: ``"relmse"`` (default: the luminance's squared error over Y² + ε, averaged
                over the pixels) or ``"mse"``.
            confidence: of the stated error interval and of a target's stop (default 0.95).
            on_pass: called after each pass with its `PassReport`; returning ``False`` stops the
                render there (the result is then `partial`), anything else goes on.
            budgets: ``"uniform"`` (default) or ``"per-pixel"``: how a render in passes spreads
                each pass's samples over the pixels, as ``lumis render --budgets`` (passes of
                even sizes).
            **params: integrator parameters, as in the scene's ``integrator`` (``samples=64``,
                ``aovs=["alpha", "sampling_variance"]``, ``mode="integrated"``); ``None``
                removes a parameter the scene sets.

        The GIL is released while the render runs. Ctrl-C (SIGINT) stops the render within a
        camera sample per thread and raises KeyboardInterrupt; the partial image is discarded
        (the CLI, by contrast, writes it marked partial).

        Raises:
            PluginError: unknown integrator or parameters it refuses (the CLI's message).
            RenderError: the render threads could not start.
            ValueError: spp is 0, or settings of a render in passes that ``lumis render`` would
                refuse (a negative target, both a target and a time, ...).
        """

def load(
    path: StrPath,
    overrides: Union[Mapping[str, Any], Sequence[str], None] = None,
) -> Scene:
    """Reads, parses and builds the RON scene at `path`, like ``lumis render``.

    Args:
        path: the scene file; its assets are found relative to it.
        overrides: values to change, as ``lumis render --set``: a dict ``{"film.width": 64,
            "integrator.type": "alpha", "bsdfs.red.reflectance": (0.8, 0.1, 0.1)}`` or a list of
            ``"path=value"`` strings (values in RON).

    Raises:
        SceneError: the file cannot be read, parsed or built; the message names the file and,
            for syntax errors, the line and column, as the CLI's does.
    """

def load_dict(scene: Mapping[str, Any], base_dir: Optional[StrPath] = None) -> Scene:
    """Builds a scene from a dict with the fields of the RON format (docs/scene-format.md).

    Structs and maps are dicts, tuples and lists are tuples or lists, plugins are dicts with a
    ``"type"``; a key whose value is ``None`` is left out (the field's default). The dict
    and the RON form of a scene give the same scene::

        lumis.load_dict({
            "camera": {"position": (0, 2, 15), "target": (0, -1.5, 2.5), "fov": 28},
            "film": {"width": 320, "height": 240},
            "integrator": {"type": "balance", "samples": 64},
            "bsdfs": {"white": {"type": "diffuse", "reflectance": 0.8}},
            "shapes": [{"type": "sphere", "bsdf": "white", "radius": 1.0}],
            "emitters": [{"type": "envmap", "radiance": 1.0}],
        })

    Args:
        scene: the scene.
        base_dir: the directory relative asset paths are resolved against (default: the
            current directory).

    Raises:
        SceneError: the scene cannot be built (messages name the file ``<dict>``).
        TypeError: a value that a scene cannot hold (a set, an object...).
    """

def plugins() -> list[dict[str, Any]]:
    """Every registered plugin (BSDFs, emitters, integrators, and BSDFs of libraries loaded by a
    scene), as ``lumis plugins`` lists them::

        {"kind": "integrator", "name": "alpha", "description": "...",
         "parameters": [{"name": "samples", "type": "integer", "default": "256",
                         "valid": "[1, ...]", "unit": "", "description": "..."}, ...]}

    ``default`` is RON text (``"required"`` when the parameter has none).
    """
