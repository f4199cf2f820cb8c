"""The compiled core is built here, at install (cffi's API mode: blobcli/core/build.py);
everything else about the package is in pyproject.toml."""

from setuptools import setup

setup(cffi_modules=["blobcli/core/build.py:ffibuilder"])
