"""The compiled core's build: the flags that keep the bits, a library that matches its sources, and a
clear message where a build cannot run."""

import shutil

import pytest

from blobcli.core import StaleBuild, check_fresh, load
from blobcli.core import build as core_build


def test_the_installed_library_is_built_from_the_sources_beside_it():
    ffi, lib = load()
    assert ffi.string(lib.bc_source_hash()).decode() == core_build.source_hash()


def test_a_library_older_than_its_sources_is_refused_with_how_to_rebuild(tmp_path):
    for path in core_build.sources() + core_build.headers():
        shutil.copy(path, tmp_path / path.name)
    built = core_build.source_hash(tmp_path)
    check_fresh(built, tmp_path)  # as built: accepted
    step = tmp_path / "step.c"
    step.write_text(step.read_text() + "\n/* edited */\n")
    with pytest.raises(StaleBuild, match=r"pip install -e \."):
        check_fresh(built, tmp_path)


def test_the_flags_keep_separate_roundings_and_no_fast_math():
    flags, _ = core_build.compiler_flags()
    assert "-ffp-contract=off" in flags and "-std=c11" in flags
    assert not any("fast-math" in f or f == "-Ofast" for f in flags)


def test_without_a_compiler_the_build_says_what_to_install(monkeypatch):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    with pytest.raises(SystemExit, match="needs a C compiler .* install one"):
        core_build.make_builder()


def test_the_api_headers_parse_and_declare_the_step():
    text = core_build.cdef_text()
    assert "bc_advance" in text and "#include" not in text


def test_the_stage_clock_has_a_slot_for_every_stage_the_step_names():
    """bc_advance's clock (step.c's LAP_ slots) is a BC_STAGE_COUNT array that pipeline.STAGES names in order."""
    from blobcli.core import load
    from blobcli.sim.pipeline import STAGES
    assert load()[1].BC_STAGE_COUNT == len(STAGES)
