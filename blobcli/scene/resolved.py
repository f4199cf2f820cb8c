"""The scene written back as TOML with every default filled in: what `blobsim check` prints, and how
`blobsim sweep` writes a swept value.
"""

from __future__ import annotations

from dataclasses import fields, replace

from .keys import DEFAULT_DURATION, STATIC_MATERIAL_KEYS, STATIC_MOTION_KEYS, Scene


def toml_value(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return str(v)


def resolved_toml(scene: Scene) -> str:
    """The scene with every default filled in, as TOML (what `blobsim check` prints)."""
    s = replace(scene.settings, name=scene.name)
    if s.steps is None:
        s = replace(s, duration=s.duration or DEFAULT_DURATION)
    o = replace(scene.output, path=str(scene.output_path))
    out = [f"# {scene.source}: {scene.blob_count} blobs, {scene.vertex_count} vertices, {scene.steps} steps"]

    def table(header, obj, keys=None):
        out.append(header)
        for f in fields(obj):
            if keys is not None and f.name not in keys:
                continue
            v = getattr(obj, f.name)
            if v is not None:
                unit = f.metadata["unit"]
                out.append(f"{f.name} = {toml_value(v)}" + (f"  # {unit}" if unit else ""))
        out.append("")

    table("[scene]", s)
    table("[output]", o)
    for b in scene.blobs:
        keys = None if b.points is None else [f.name for f in fields(b) if f.name not in ("vertices",)]
        table("[[blob]]", b, keys)
    from ..colliders import COLLIDERS
    for st in scene.statics:
        motion = [k for k in STATIC_MOTION_KEYS if k not in ("load_direction", "mass") or st.load is not None]
        table("[[static]]", st, ["kind", *COLLIDERS[st.kind].keys, *STATIC_MATERIAL_KEYS, *motion])
    for sc in scene.schedules:
        table("[[schedule]]", sc)
    return "\n".join(out).rstrip() + "\n"
