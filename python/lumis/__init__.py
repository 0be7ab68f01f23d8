"""lumis: a physically based renderer for multiple importance sampling research.

Scenes in, numpy arrays out::

    import lumis
    scene = lumis.load("scenes/veach.ron", overrides={"film.width": 160, "film.height": 120})
    result = scene.render(integrator="alpha", spp=4, samples=16, aovs=["alpha"])
    result["color"].shape          # (120, 160, 3), float32, linear Rec. 709 RGB
    result["alpha"][..., 0]        # the combined α map
    result.write("veach.exr")      # the same files as `lumis render -o veach.exr`

Studies of the speed/accuracy trade, as ``lumis study`` runs them, return their tables::

    study = lumis.study("scenes/paper/03.ron", "out", integrators="balance,light,alpha",
                        budgets=[4, 8, 16], overrides={"film.width": 64, "film.height": 64})
    study.results[0]["ratio_relative_variance"]    # and its _lo, _hi: the 95 % interval
    study.dataframe("curves")                        # with pandas installed

A render to a target error (or in a time) runs in passes and states its error::

    result = scene.render(target_error=0.01, on_pass=lambda p: print(p))
    result.error, result.error_interval    # the estimate and its 95 % interval

See ``help(lumis.Scene.render)``, ``help(lumis.study)`` and ``lumis.plugins()``.
"""

from ._lumis import (
    LumisError,
    OutputError,
    PassReport,
    PluginError,
    RenderError,
    RenderResult,
    Scene,
    SceneError,
    load,
    load_dict,
    plugins,
)
from ._study import Study, study

__all__ = [
    "LumisError",
    "OutputError",
    "PassReport",
    "PluginError",
    "RenderError",
    "RenderResult",
    "Scene",
    "SceneError",
    "Study",
    "load",
    "load_dict",
    "plugins",
    "study",
]
