"""The numba decorators every kernel uses, and the builds of the step for one scene's configuration.

cache=True keeps compiled kernels on disk between runs; error_model="numpy" lets
divisions skip the zero check so loops vectorize; fastmath stays off because it
reorders sums, and runs must be bit-identical. Small helpers called per vertex or per
edge (`inline_kernel`) are compiled once each and inlined into their callers by LLVM
(forceinline: the alwaysinline attribute). Left as calls, the perimeter sweep ran 7×
slower; inlined at the numba IR level (inline="always"), each was typed and lowered
again at every call site, and the contact resolve alone took 37 s of a cold compile.
A helper has no Python entry (no_cpython_wrapper): only kernels call it.

`ir_inline_kernel` (numba IR inlining) is kept for the contact stages' per-contact
bodies, each called at one place: inlined by LLVM instead, the parallel build's contact
resolve ran 1.9× slower at 1,000 blobs (27.7 against 14.2 ms per step, stage clock; the
serial build was not slower). Why is not known; the measurement decided (dev, 2026-11-26).
"""

import functools
import hashlib
import types
from pathlib import Path

import numba

FLAGS = dict(cache=True, error_model="numpy", nogil=True, no_cfunc_wrapper=True)  # (no C callback is taken of a kernel)
kernel = numba.njit(**FLAGS)
inline_kernel = numba.njit(forceinline=True, no_cpython_wrapper=True, **FLAGS)
ir_inline_kernel = numba.njit(inline="always", **FLAGS)

_STAGES: dict[int, tuple] = {}  # id(serial build) -> (serial build, its Python function)
_BUILDS: dict[tuple, object] = {}  # (id(serial build), parallel, bound configuration, entry) -> that build
_ASKED: dict[tuple, object] = {}  # (id(serial build), parallel, whole configuration, entry) -> its build: the step asks
#                                   once per compiled call, and finding what a kernel reads walks its callees


def stage_kernel(fn):
    """A stage kernel: returns its serial build (numba.prange runs as range), for calls that need no
    configuration; `build` gives the build for one scene's configuration, serial or parallel.

    A stage kernel may call other stage kernels (the step's driver calls them all), and may read
    configuration names: module globals in capitals (COLLIDES, METHOD, ...) that say what the scene
    uses. `build` compiles a renamed copy of the code in which those names are the scene's values
    and each stage kernel it calls is that stage's build for the same configuration. numba reads a
    global as a compile-time constant and prunes a branch on constants before typing it
    (`if COLLIDES:` with COLLIDES false), so a build compiles only the stages its scene runs.

    Serial and parallel builds give the same bits: a prange loop's iterations write only their own
    slots. A parallel build is loaded from the disk cache only once numba's threading layer is up
    (`build` starts it): the step's driver has no prange loop of its own, so it is compiled with
    parallel=False, and numba, loading it from the cache, need not start the threads its parallel
    stages run on (numba issue #8578; its workaround). Seen (dev, 2026-11-26, gdb): one cached build
    of a 300-blob pile with sleeping crashed on its first call, a jump to a null pointer, in every
    new process that called pipeline.advance, and ran in every one that had started the threads
    first (`numba.get_num_threads()`; `blobsim run` does, to pick its thread count). How that cache
    entry was made is not known: compiled and then loaded in two clean processes, the same build
    ran without the threads started.

    Why both (dev, `blobsim bench`): a parallel launch costs ~2 µs, which made a one-blob step 3× slower,
    while at 1,000 blobs the parallel builds are far faster, on one thread too (the perimeter sweep:
    16.7 ns per edge serial, 7.1 parallel on one thread, 3.7 on two).
    """
    serial = kernel(fn)
    _STAGES[id(serial)] = (serial, fn)
    return serial


def _callees(fn):
    """The stage kernels that fn's code names."""
    return [fn.__globals__[name] for name in fn.__code__.co_names
            if id(fn.__globals__.get(name)) in _STAGES]


def _reads(fn, names) -> set:
    """Which of `names` fn reads, itself or through the stage kernels it calls."""
    found = set(fn.__code__.co_names) & set(names)
    for callee in _callees(fn):
        found |= _reads(_STAGES[id(callee)][1], names)
    return found


def _has_prange(fn) -> bool:
    """Whether fn, or a stage kernel it calls, has prange loops."""
    return "prange" in fn.__code__.co_names or any(_has_prange(_STAGES[id(c)][1]) for c in _callees(fn))


@functools.cache
def source_token() -> str:
    """8 hex digits of a hash of the simulation's source (blobcli/sim, geometry, colliders, this file).
    numba keys a cached kernel by its own file's stamp only, while a build links the code of the stages
    it calls from other files: without this token in its name, a changed stage would leave the step's
    cached build running the old one."""
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted([*root.glob("sim/*.py"), root / "geometry.py", root / "colliders.py", root / "jit.py"]):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:8]


def build(serial, is_parallel: bool = False, config: dict | None = None, entry: bool = True):
    """The build of a stage kernel for one configuration (a dict of configuration names to bool or
    int values), serial or parallel: the serial build itself when the kernel reads none of those
    names and has no prange loop to run in parallel, else a renamed copy of its code compiled with
    them bound. The name says the bound values (numba's disk cache keys a kernel by its name and
    bytecode, not its globals or flags, so two builds of one function under one name would
    overwrite each other's cache: numba issue #6845) and the source it was built from
    (`source_token`). Built on first use, when every module it names is loaded; compiled on its
    first call (or loaded from the disk cache). The builds it calls have no Python entry (entry
    False: no wrapper to unbox arguments from Python objects, a tenth of the step's cold compile)."""
    config = config or {}
    asked = (id(serial), is_parallel, tuple(sorted(config.items())), entry)
    if asked in _ASKED:
        return _ASKED[asked]
    _, fn = _STAGES[id(serial)]
    bound = tuple(sorted((name, config[name]) for name in _reads(fn, config)))
    parallel = is_parallel and _has_prange(fn)
    if parallel:  # the threads its stages run on, up before a cached build is loaded (stage_kernel)
        numba.get_num_threads()
    if not bound and not parallel:
        _ASKED[asked] = serial
        return serial
    key = (id(serial), parallel, bound, entry)
    twin = _BUILDS.get(key)
    if twin is None:
        scope = dict(fn.__globals__)
        scope.update(bound)
        suffix = ("".join(f"_{name.lower()}{int(value)}" for name, value in bound) + ("_parallel" if parallel else "")
                  + ("" if entry else "_inner") + f"_src{source_token()}")
        code = fn.__code__.replace(co_name=fn.__name__ + suffix, co_qualname=fn.__qualname__ + suffix)
        function = types.FunctionType(code, scope, code.co_name, fn.__defaults__, fn.__closure__)
        # parallel=True where the code has prange loops of its own; a stage that only calls others
        # (the driver, say) is parallel through them
        own_loops = parallel and "prange" in fn.__code__.co_names
        twin = _BUILDS[key] = numba.njit(parallel=own_loops, no_cpython_wrapper=not entry, **FLAGS)(function)
        for name in fn.__code__.co_names:  # after registering the twin: a module's kernels name each other
            if id(scope.get(name)) in _STAGES:
                scope[name] = build(scope[name], is_parallel, config, entry=False)
    _ASKED[asked] = twin
    return twin


def parallel(serial):
    """The parallel build of a stage kernel that reads no configuration."""
    return build(serial, True)


def in_disk_cache(dispatcher, args) -> bool | None:
    """Whether numba's disk cache holds `dispatcher` compiled for these arguments (so a first call
    only loads it): True or False, or None when numba's cache cannot be asked (its internals moved)."""
    if dispatcher.overloads:
        return True
    try:
        sig = tuple(dispatcher.typeof_pyval(a) for a in args)
        cache = dispatcher._cache
        key = cache._index_key(sig, dispatcher.targetctx.codegen())
        return key in cache._cache_file._load_index()
    except Exception:  # a private API: any change in numba means "cannot tell", never a failed run
        return None
