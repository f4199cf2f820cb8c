"""Line numbers of TOML keys, so validation errors can say `file:line: key.path`.

tomli parses values but forgets where they came from. This scanner walks the text once
and maps every key path it defines to the 1-based line of its definition:

    [scene]           -> ("scene",)
    dt = 0.01         -> ("scene", "dt")
    [[blob]]          -> ("blob", 0)      (the n-th array-of-tables entry gets index n)
    radius = 0.5      -> ("blob", 0, "radius")

It only needs to be right for documents tomli has already accepted; inside multi-line
arrays and strings it skips lines, so a value spanning lines maps to its key's line.
"""

from __future__ import annotations

_BARE = set("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")


def _split_key(text: str) -> list[str]:
    """Split a (possibly dotted, possibly quoted) TOML key into its parts."""
    parts, cur, i = [], "", 0
    while i < len(text):
        ch = text[i]
        if ch in "\"'":
            end = text.find(ch, i + 1)
            end = len(text) if end < 0 else end
            cur += text[i + 1:end]
            i = end + 1
            continue
        if ch == ".":
            parts.append(cur.strip())
            cur = ""
        else:
            cur += ch
        i += 1
    parts.append(cur.strip())
    return parts


def _bracket_delta(line: str, state: dict) -> int:
    """Net [ ] / { } depth change of a value line, ignoring strings and comments."""
    depth, i = 0, 0
    while i < len(line):
        if state["ml"]:  # inside a multi-line string
            end = line.find(state["ml"], i)
            if end < 0:
                return depth
            i = end + 3
            state["ml"] = None
            continue
        ch = line[i]
        if ch == "#":
            break
        if line.startswith('"""', i) or line.startswith("'''", i):
            state["ml"] = line[i:i + 3]
            i += 3
            continue
        if ch in "\"'":
            j = i + 1
            while j < len(line) and line[j] != ch:
                j += 2 if (ch == '"' and line[j] == "\\") else 1
            i = j + 1
            continue
        if ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        i += 1
    return depth


def key_lines(text: str) -> dict[tuple, int]:
    """Map key paths (tuples of str and int) to the 1-based line defining them."""
    lines: dict[tuple, int] = {}
    counters: dict[tuple, int] = {}
    table: tuple = ()
    depth = 0
    state = {"ml": None}
    for number, raw in enumerate(text.splitlines(), start=1):
        if depth > 0 or state["ml"]:
            depth += _bracket_delta(raw, state)
            continue
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("[["):
            name = tuple(_split_key(line[2:line.index("]]")]))
            index = counters.get(name, 0)
            counters[name] = index + 1
            table = name + (index,)
            lines.setdefault(name, number)
            lines[table] = number
            continue
        if line.startswith("["):
            table = tuple(_split_key(line[1:line.index("]")]))
            lines[table] = number
            continue
        if "=" in line:
            key, _, value = line.partition("=")
            path = table + tuple(_split_key(key))
            for k in range(len(table) + 1, len(path) + 1):
                lines.setdefault(path[:k], number)
            depth = _bracket_delta(value, state)
    return lines


def line_of(lines: dict[tuple, int], path: tuple) -> int:
    """Line of `path`, or of its nearest defined ancestor (1 if none is)."""
    for k in range(len(path), 0, -1):
        if path[:k] in lines:
            return lines[path[:k]]
    return 1
