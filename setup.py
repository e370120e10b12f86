"""Builds plem's compiled core (plem.control._core) with the C compiler and the Python headers, SOEM (vendored
whole in third_party/soem) compiled into it; the rest of the package is described in pyproject.toml."""

from pathlib import Path

from setuptools import Extension, setup

SOURCES = Path("src/plem/control/csrc")
SOEM = Path("third_party/soem")
SOEM_VERSION = "v1.4.0"
#: SOEM's Linux build: its library, OS abstraction and raw-socket driver, as its own CMake build compiles them.
SOEM_SOURCES = sorted(str(p) for p in [*SOEM.glob("soem/*.c"), SOEM / "osal/linux/osal.c", *SOEM.glob("oshw/linux/*.c")])
SOEM_INCLUDES = [str(SOEM / d) for d in ("soem", "osal", "osal/linux", "oshw/linux")]
#: C11, every warning an error, no symbols leaking beyond the module. SOEM's headers are system headers to it:
#: the core's warnings stay its own.
FLAGS = ["-std=c11", "-O2", "-fno-math-errno", "-Wall", "-Wextra", "-Werror", "-Wshadow", "-Wstrict-prototypes", "-fvisibility=hidden",
         "-D_GNU_SOURCE", f'-DPLEM_SOEM_VERSION="{SOEM_VERSION}"'] + [f"-isystem{d}" for d in SOEM_INCLUDES]

setup(
    libraries=[("soem", {"sources": SOEM_SOURCES, "include_dirs": SOEM_INCLUDES,
                         "cflags": ["-O2", "-fPIC", "-fvisibility=hidden", "-D_GNU_SOURCE"]})],
    ext_modules=[Extension("plem.control._core", sources=sorted(str(p) for p in SOURCES.glob("*.c")),
                           depends=sorted(str(p) for p in [*SOURCES.glob("*.h"), *SOEM.glob("soem/*.h")]),
                           extra_compile_args=FLAGS, libraries=["m", "pthread", "rt"])])
