"""Regenerate the golden reference trajectories and the determinism hash. Run on purpose only:

    python tests/golden/regenerate.py

Never run by a test. Commit the new files with a note saying why the physics changed.
The hash file is rewritten with this machine's versions only: hashes recorded under other
versions no longer hold once the physics changed.
"""

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE.parent))

from golden_cases import (  # noqa: E402
    GOLDEN,
    HASH_SCENE,
    HASH_STEPS,
    final_positions_hash,
    version_key,
)

from blobcli import load_scene, simulate  # noqa: E402
from blobcli.scene.schema import with_overrides  # noqa: E402


def main():
    for name, steps, every in GOLDEN:
        scene = with_overrides(load_scene(ROOT / "scenes" / f"{name}.toml"), steps=steps)
        from dataclasses import replace
        scene = replace(scene, output=replace(scene.output, every=every))
        result = simulate(scene, HERE / f"{name}.h5")
        print(result.summary())
    hashes_file = HERE / "hashes.json"
    hashes = {version_key(): final_positions_hash(HASH_SCENE, HASH_STEPS)}
    hashes_file.write_text(json.dumps(hashes, indent=2, sort_keys=True) + "\n")
    print(f"hash for {version_key()}: {hashes[version_key()]}")


if __name__ == "__main__":
    main()
