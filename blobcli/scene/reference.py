"""The scene reference of docs/scenes.md, generated from the keys' dataclass fields
(`python -m blobcli.scene.reference`, or `python -m blobcli.scene.schema`, prints it).
"""

from __future__ import annotations

from dataclasses import fields

from .keys import TABLES
from .resolved import toml_value


def reference_markdown() -> str:
    """The scene reference of docs/scenes.md, generated from the dataclass fields."""
    out = []
    for name, cls in TABLES.items():
        header = f"[[{name}]]" if name in ("blob", "static", "schedule") else f"[{name}]"
        out.append(f"### `{header}`\n\n| key | default | unit | meaning |\n|---|---|---|---|")
        for f in fields(cls):
            d = f.default
            if d is None:
                default = "—"
            elif isinstance(d, float) and d == 1 / 60:
                default = "`1/60` (0.01667)"
            else:
                default = f"`{toml_value(d)}`"
            out.append(f"| `{f.name}` | {default} | {f.metadata['unit'] or ''} | {f.metadata['doc']} |")
        out.append("")
    return "\n".join(out)


if __name__ == "__main__":  # python -m blobcli.scene.reference: print the scene reference of docs/scenes.md
    print(reference_markdown(), end="")
