"""Build the compiled core with cffi in API mode (as pymunk builds Chipmunk): `pip install -e .` runs
`ffibuilder` through setup.py's `cffi_modules`, which compiles every C file of blobcli/core into the
extension module blobcli.core._blobcore.

cffi reads the declarations of `blobcore.h` and of every header whose first line says "(read by
cffi)": the driver's and the stages' entry points (tests call some stages one by one) and the sizes
Python reads (lib.BC_*).

Flags: -std=c11 -O3 -ffp-contract=off (GNU C would fuse a*b + c into one rounding; the step's bits
are those of separate roundings), never -ffast-math; -fno-trapping-math lets a loop with a comparison
in it run on vector registers (no floating-point exception is ever unmasked: it changes no result;
vector_loops.h). OpenMP where the compiler has it (-fopenmp);
without it the same code runs serially, with the same bits. BLOBSIM_SANITIZE=1 in the environment
builds with AddressSanitizer and UndefinedBehaviorSanitizer instead (CI's sanitizer tier, .ci/run).

`python -m blobcli.core.build` rebuilds the extension in place, without pip: for work on the C.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
MODULE = "blobcli.core._blobcore"
CFFI_MARK = "(read by cffi)"
BASE_FLAGS = ["-std=c11", "-O3", "-ffp-contract=off", "-fno-math-errno", "-fno-trapping-math"]
SANITIZE_FLAGS = ["-std=c11", "-O1", "-g", "-ffp-contract=off", "-fno-math-errno", "-fno-omit-frame-pointer",
                  "-fsanitize=address,undefined", "-fno-sanitize-recover=undefined"]
SANITIZE = "BLOBSIM_SANITIZE"


def sources(root: Path = HERE) -> list[Path]:
    """The C files of the core, in a fixed order."""
    return sorted(root.glob("*.c"))


def headers(root: Path = HERE) -> list[Path]:
    return sorted(root.glob("*.h"))


def source_hash(root: Path = HERE) -> str:
    """16 hex digits of a hash of every C source and header: the library says which it was built from."""
    digest = hashlib.sha256()
    for path in sources(root) + headers(root):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def api_headers(root: Path = HERE) -> list[Path]:
    """blobcore.h, then each header marked "(read by cffi)" on its first line."""
    return [root / "blobcore.h"] + [h for h in headers(root) if h.name != "blobcore.h"
                                    and CFFI_MARK in h.read_text().split("\n", 1)[0]]


def cdef_text(root: Path = HERE) -> str:
    """The declarations cffi reads: the API headers without the lines of the preprocessor but integer #defines."""
    keep = re.compile(r"#define\s+\w+\s+-?\d+\s*(/\*.*\*/)?\s*$")
    lines = []
    for path in api_headers(root):
        for line in path.read_text().splitlines():
            if line.lstrip().startswith("#") and not keep.match(line.strip()):
                continue
            lines.append(line)
    return "\n".join(lines)


def _compiles(flags: list[str]) -> bool:
    """Whether the C compiler Python was built with accepts these flags (and links them)."""
    cc = _compiler()
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "probe.c"
        src.write_text("#include <omp.h>\nint main(void) { return omp_get_max_threads() > 0 ? 0 : 1; }\n")
        try:
            run = subprocess.run([*cc, *flags, str(src), "-o", str(Path(tmp) / "probe")], capture_output=True)
        except OSError:
            return False
        return run.returncode == 0


def _compiler() -> list[str]:
    """The C compiler setuptools will call: $CC, else the one Python was built with."""
    return (os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc").split()


def compiler_flags() -> tuple[list[str], list[str]]:
    """(compile flags, link flags) for this machine's compiler."""
    sanitize = os.environ.get(SANITIZE) == "1"
    flags = list(SANITIZE_FLAGS if sanitize else BASE_FLAGS)
    link = ["-fsanitize=address,undefined"] if sanitize else []
    if _compiles(["-fopenmp"]):
        flags.append("-fopenmp")
        link.append("-fopenmp")
    return flags, link


def _check_compiler() -> None:
    """Fail with a line that says what to install when there is no C compiler or no Python headers."""
    cc = _compiler()[0]
    if shutil.which(cc) is None:
        sys.exit(f"blobsim: building the compiled core needs a C compiler ({cc!r} not found): install one "
                 "(Debian/Ubuntu: apt-get install gcc; macOS: xcode-select --install), then pip install again")
    include = Path(sysconfig.get_paths()["include"]) / "Python.h"
    if not include.exists():
        sys.exit(f"blobsim: building the compiled core needs Python's headers ({include} not found): install them "
                 "(Debian/Ubuntu: apt-get install python3-dev), then pip install again")


def make_builder(module: str = MODULE, root: Path = HERE, relative: bool = False):
    """A cffi FFI set up to build `module` from the core's C files. `relative`: the paths relative to the
    working directory, as setup.py's build wants them (pip runs it from the project root); cffi's own
    compile, which works in a folder of its own, wants them absolute."""
    from cffi import FFI

    _check_compiler()
    flags, link = compiler_flags()
    builder = FFI()
    builder.cdef(cdef_text(root))
    files = sources(root)
    preamble = "".join(f'#include "{h.name}"\n' for h in api_headers(root))
    def path(p: Path) -> str:
        return os.path.relpath(p) if relative else str(p)
    builder.set_source(module, preamble, sources=[path(f) for f in files], include_dirs=[path(root)],
                       extra_compile_args=flags, extra_link_args=link,
                       define_macros=[("BC_SOURCE_HASH", f'"{source_hash(root)}"')], libraries=["m"])
    return builder


ffibuilder = make_builder(relative=True) if __name__ == "__cffi__" else None  # (setup.py's cffi_modules)


def build_in_place() -> Path:
    """Compile the extension into blobcli/core, as an editable install does."""
    builder = make_builder()
    with tempfile.TemporaryDirectory() as tmp:
        built = Path(builder.compile(tmpdir=tmp, verbose=False))
        target = HERE / built.name
        staged = target.with_name(target.name + ".new")
        shutil.copy2(built, staged)
        os.replace(staged, target)  # a new file: a process that has the old one loaded keeps it
    return target


if __name__ == "__main__":
    print(build_in_place())
