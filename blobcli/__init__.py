"""blobsim: batch simulator for 2D soft blobs with exact area projection.

The public API (imported lazily, so the command line starts fast):

    scene = load_scene("scenes/gish.toml")      # validated, frozen Scene
    model, state = build(scene)                 # static arrays, changing state
    step(state, model, build_params(scene))     # advance one step
    result = simulate(scene, "out.h5")          # a whole run, to an H5MD file
    traj = read_trajectory("out.h5")
"""

__version__ = "0.1.0"

__all__ = ["load_scene", "parse_scene", "SceneError", "build", "build_params", "step", "simulate",
           "read_trajectory", "blob_measures", "__version__"]

_HOMES = {"load_scene": "scene.schema", "parse_scene": "scene.schema", "SceneError": "scene.schema",
          "build": "sim.model", "build_params": "sim.model", "step": "sim.pipeline", "simulate": "io.run",
          "read_trajectory": "io.h5md", "blob_measures": "sim.measure"}


def __getattr__(name):
    if name in _HOMES:
        import importlib
        return getattr(importlib.import_module(f".{_HOMES[name]}", __name__), name)
    raise AttributeError(f"module 'blobcli' has no attribute {name!r}")
