"""Builds sweptccd._sweptccd with the project's CMake (target sweptccd_python)
from the repository this folder sits in, then packages it with the Python
files. SWEPTCCD_PREBUILT_EXTENSION=PATH packages an extension already built
(by `cmake --build build --target sweptccd_python`) instead of building one;
SWEPTCCD_CMAKE_BUILD_DIR picks the CMake build folder (default: a folder
under setuptools' build_temp)."""

import glob
import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

REPO = Path(__file__).resolve().parent.parent


class CMakeBuild(build_ext):
    def build_extension(self, ext: Extension) -> None:
        dest = Path(self.get_ext_fullpath(ext.name))
        built = os.environ.get("SWEPTCCD_PREBUILT_EXTENSION")
        if not built:
            build = Path(os.environ.get("SWEPTCCD_CMAKE_BUILD_DIR",
                                        Path(self.build_temp).resolve() / "cmake"))
            launcher = ["-DCMAKE_CXX_COMPILER_LAUNCHER=ccache",
                        "-DCMAKE_C_COMPILER_LAUNCHER=ccache"] if shutil.which("ccache") else []
            subprocess.check_call(["cmake", "-S", str(REPO), "-B", str(build),
                                   "-DCMAKE_BUILD_TYPE=Release", "-DSWEPTCCD_BUILD_TESTS=OFF",
                                   f"-DPython3_EXECUTABLE={sys.executable}", *launcher])
            subprocess.check_call(["cmake", "--build", str(build), "--target", "sweptccd_python",
                                   "-j", str(os.cpu_count() or 2)])
            found = glob.glob(str(build / "python" / "sweptccd" / "_sweptccd*.so"))
            if len(found) != 1:
                raise RuntimeError(f"expected one _sweptccd*.so in {build}, found {found}")
            built = found[0]
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built, dest)


setup(ext_modules=[Extension("sweptccd._sweptccd", sources=[])],
      cmdclass={"build_ext": CMakeBuild})
