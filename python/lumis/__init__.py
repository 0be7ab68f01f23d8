"""lumis: a physically based renderer for multiple importance sampling research.

Scenes in, numpy arrays out::

    import lumis
    scene = lumis.load("scenes/veach.ron", overrides={"film.width": 160, "film.height": 120})
    result = scene.render(integrator="alpha", spp=4, samples=16, aovs=["alpha"])
    result["color"].shape          # (120, 160, 3), float32, linear Rec. 709 RGB
    result["alpha"][..., 0]        # the combined α map
    result.write("veach.exr")      # the same files as `lumis render -o veach.exr`

See ``help(lumis.Scene.render)`` and ``lumis.plugins()``.
"""

from ._lumis import (
    LumisError,
    OutputError,
    PluginError,
    RenderError,
    RenderResult,
    Scene,
    SceneError,
    load,
    load_dict,
    plugins,
)

__all__ = [
    "LumisError",
    "OutputError",
    "PluginError",
    "RenderError",
    "RenderResult",
    "Scene",
    "SceneError",
    "load",
    "load_dict",
    "plugins",
]
