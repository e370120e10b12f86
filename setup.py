"""Builds plem's compiled core (plem.control._core) with the C compiler and the Python headers; the rest of the
package is described in pyproject.toml."""

from pathlib import Path

from setuptools import Extension, setup

SOURCES = Path("src/plem/control/csrc")
#: C11, every warning an error, no symbols leaking beyond the module.
FLAGS = ["-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-Wshadow", "-Wstrict-prototypes", "-fvisibility=hidden",
         "-D_GNU_SOURCE"]

setup(ext_modules=[Extension("plem.control._core", sources=sorted(str(p) for p in SOURCES.glob("*.c")),
                             depends=sorted(str(p) for p in SOURCES.glob("*.h")), extra_compile_args=FLAGS,
                             libraries=["m", "pthread"])])
