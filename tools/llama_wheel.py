"""Build llama-cpp-python for this machine without AMX kernels (once, into a wheel folder) and
install it into the running interpreter's environment.

llama-cpp-python compiles llama.cpp with ``-march=native``, which turns on its AMX matrix
kernels wherever the CPU reports AMX. On some machines of this project's kind those kernels
crash the process at the first prompt (a fault in ``ggml_backend_amx_mul_mat``), and GLOBE's
scorer needs kernels whose rows do not depend on the rest of their batch, which tile kernels do
not give. So the build keeps everything ``-march=native`` offers except AMX. The wheel is built
once per machine (4-7 minutes on 2 cores) for the version pinned in pyproject.toml's ``llm``
extra and reused by every new virtual environment; ``make setup`` runs this before installing
the project. Usage: python tools/llama_wheel.py WHEEL_DIR
"""

from __future__ import annotations

import os
import platform
import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
AMX_OFF = "-mno-amx-tile -mno-amx-int8 -mno-amx-bf16"


def pinned_version() -> str:
    """The ``llama-cpp-python==X`` pin of the ``llm`` extra."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    for req in project["optional-dependencies"]["llm"]:
        match = re.fullmatch(r"llama-cpp-python(\[[^\]]*\])?==([\w.]+)", req.replace(" ", ""))
        if match:
            return match.group(2)
    sys.exit("pyproject.toml: the llm extra pins no llama-cpp-python==VERSION")


def cmake_args() -> str:
    """CMAKE_ARGS for the build: the caller's, plus AMX off on x86 (the flags exist only there)."""
    args = os.environ.get("CMAKE_ARGS", "")
    if platform.machine().lower() in ("x86_64", "amd64"):
        if re.search(r"-DCMAKE_(C|CXX)_FLAGS\b", args):  # CMake keeps the last -D: one would be lost
            sys.exit("CMAKE_ARGS sets CMAKE_C_FLAGS or CMAKE_CXX_FLAGS, which this build needs for "
                     f"'{AMX_OFF}': add those flags to yours and build with pip yourself, or unset them")
        args += f" -DCMAKE_C_FLAGS='{AMX_OFF}' -DCMAKE_CXX_FLAGS='{AMX_OFF}'"
    return args.strip()


def usable(wheel: Path) -> bool:
    """Whether ``wheel`` (name-version[-build]-python-abi-platform.whl) installs into this
    interpreter: a wheel folder may hold builds for other Pythons or machines."""
    python, abi, plat = wheel.name[:-len(".whl")].split("-")[-3:]
    here = f"cp{sys.version_info.major}{sys.version_info.minor}"
    return (any(tag in ("py3", here) for tag in python.split("."))
            and any(tag in ("none", "abi3", here) for tag in abi.split("."))
            and any(tag == "any" or tag.endswith(platform.machine().lower()) for tag in plat.split(".")))


def main() -> None:
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    wheels = Path(sys.argv[1]).resolve()
    version = pinned_version()
    built = sorted(w for w in wheels.glob(f"llama_cpp_python-{version}-*.whl") if usable(w))
    if not built:
        wheels.mkdir(parents=True, exist_ok=True)
        print(f"building llama-cpp-python {version} without AMX kernels into {wheels} (4-7 minutes, once)", flush=True)
        subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-cache-dir", "--no-binary",
                        "llama-cpp-python", "-w", str(wheels), f"llama-cpp-python=={version}"],
                       env=dict(os.environ, CMAKE_ARGS=cmake_args()), check=True)
        built = sorted(w for w in wheels.glob(f"llama_cpp_python-{version}-*.whl") if usable(w))
        if not built:
            sys.exit(f"pip reported success but left no llama_cpp_python-{version} wheel in {wheels}")
    # --force-reinstall: an environment may hold a build of the same version with AMX kernels
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--force-reinstall", str(built[-1])],
                   check=True)


if __name__ == "__main__":
    main()
