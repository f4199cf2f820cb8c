"""What the golden references hold, shared by the tests and tests/golden/regenerate.py."""

import hashlib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOLDEN = [  # (scene, steps, record every): small, and they exercise statics, collisions, heavy loads
    ("gish", 240, 10),
    ("crusher", 120, 10),
    ("pile", 90, 15),
]
HASH_SCENE, HASH_STEPS = "pile", 240  # chaotic: 120 blobs tumbling into a pile


def version_key() -> str:
    """Bit-identical results are promised for the same machine, compiler and numpy (the model's arrays): the
    hash's key."""
    import platform

    import numpy

    from blobcli.core import load
    ffi, lib = load()
    return f"{platform.machine()} {ffi.string(lib.bc_compiler()).decode()} numpy {numpy.__version__}"


def final_positions_hash(scene_name: str, steps: int) -> str:
    """sha256 of the final positions' bytes after `steps` steps (Box2D's determinism check)."""
    from blobcli import build, build_params, load_scene, step
    from blobcli.scene.schema import with_overrides
    scene = with_overrides(load_scene(ROOT / "scenes" / f"{scene_name}.toml"), steps=steps)
    model, state = build(scene)
    params = build_params(scene)
    for _ in range(steps):
        step(state, model, params)
    return hashlib.sha256(state.pos.tobytes()).hexdigest()
