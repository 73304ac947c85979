#!/usr/bin/env python3
"""CTest `blender_import` (label blender; docs/export.md): the Blender recipe
tools/blender_import_eco.py run in Blender on the files of `eco instance` for a small scene,
then tests/blender/check_import.py in the same Blender session checks the scene (prototype
objects, one instance per plant of its prototype at its position, rotation and scale, the
ground mesh and its images), saves it as a .blend and checks it again after reopening.

    ECO_BINARY=build/apps/eco tests/blender/run.py

Exit 77 (CTest SKIP_RETURN_CODE) with a message when `blender` is not installed
(`apt-get install -y blender`, Debian 12: Blender 3.4).
"""

import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.normpath(os.path.join(HERE, "..", ".."))


def main():
    blender = shutil.which("blender")
    if blender is None:
        print("SKIPPED: blender is not installed (apt-get install -y blender; docs/export.md)")
        return 77
    eco = os.environ.get("ECO_BINARY", os.path.join(SOURCE, "build", "apps", "eco"))
    work = tempfile.mkdtemp(prefix="eco-blender-test-")
    try:
        def run_eco(*args):
            r = subprocess.run([eco, "--quiet", *args], cwd=work, capture_output=True, text=True)
            if r.returncode != 0:
                raise SystemExit(f"eco {' '.join(args)} failed ({r.returncode}):\n{r.stdout}{r.stderr}")

        # A 40 m x 40 m scene: a few thousand plants of about 20 prototypes.
        run_eco("terrain", "generate", "--out", "terrain.h5", "--width", "40", "--height", "40", "--cell-size", "1",
                "--seed", "4")
        run_eco("chm", "generate", "--terrain", "terrain.h5", "--out", "chm.h5", "--seed", "2", "--sketch-seed", "3")
        run_eco("abiotics", "--terrain", "terrain.h5", "--out", "abiotics.h5", "--sun-step", "120")
        run_eco("canopy", "--terrain", "terrain.h5", "--chm", "chm.h5", "--abiotics", "abiotics.h5", "--out", "canopy.h5")
        run_eco("simulate", "--abiotics", "abiotics.h5", "--canopy", "canopy.h5", "--terrain", "terrain.h5",
                "--crop", "5,5,35,35", "--years", "3", "--seed", "5", "--out", "sim.h5")
        run_eco("analyse", "sim.h5", "--out", "db.h5", "--kmax", "2")
        run_eco("synth", "--terrain", "terrain.h5", "--canopy", "canopy.h5", "--database", "db.h5",
                "--abiotics", "abiotics.h5", "--out", "scene.h5")
        run_eco("instance", "scene.h5", "--prototypes", "3", "--seed", "7", "--out", "inst")
        # Blender's Python is Debian's (its numpy from python3-numpy): a pyenv interpreter's
        # directory first on PATH (pyenv's shim puts it there) makes it miss numpy.
        env = dict(os.environ, PATH=os.pathsep.join(p for p in os.environ.get("PATH", "").split(os.pathsep)
                                                    if "/.pyenv/" not in p))
        r = subprocess.run([blender, "--background", "--factory-startup", "--python-exit-code", "1",
                            "--python", os.path.join(SOURCE, "tools", "blender_import_eco.py"),
                            "--python", os.path.join(HERE, "check_import.py"),
                            "--", os.path.join(work, "inst"), os.path.join(work, "scene.blend")],
                           capture_output=True, text=True, env=env)
        print("\n".join(line for line in r.stdout.splitlines() if not line.startswith("eco: species")))
        print(r.stderr, file=sys.stderr)
        if r.returncode != 0 or "blender check: ok" not in r.stdout:
            print(f"FAILED: blender exited {r.returncode}")
            return 1
        return 0
    finally:
        if not os.environ.get("ECO_KEEP_TEST_FILES"):
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
