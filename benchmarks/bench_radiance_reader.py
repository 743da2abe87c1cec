"""Speed of the Radiance scene reader (lsadphoto.solver.formats.radiance).

Run from the repository root: ``PYTHONPATH=$PWD python benchmarks/bench_radiance_reader.py``
(needs ../shared/realdata for the second case and pyradiance's ies2rad/genbox for the third).
"""

import subprocess
import tempfile
import time
from pathlib import Path

from lsadphoto.solver import read_radiance_scene, read_scene
from lsadphoto.solver.formats.radiance import radiance_programs

REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"


def main():
    quads = ("void plastic g 0 0 5 .5 .5 .5 0 0\nvoid light l 0 0 3 1 1 1\n"
             "l polygon p 0 0 12 0 0 9 1 0 9 1 1 9 0 1 9\n"
             + "".join(f"g polygon q{i}_{j} 0 0 12 {i} {j} 0 {i + 1} {j} 0 {i + 1} {j + 1} 0 {i} {j + 1} 0\n"
                       for i in range(100) for j in range(100)))
    cases = [("10 000 quads (text)", lambda: read_radiance_scene(quads)),
             ("constellation.rad: 10 light spheres at ε = 1e-3",
              lambda: read_scene(REALDATA / "radiance" / "renders" / "constellation.rad"))]
    folder = Path(tempfile.mkdtemp())
    bin_ = radiance_programs()
    if bin_ is not None:
        subprocess.run([str(bin_ / "ies2rad"), "-dm", "-o", str(folder / "lum"),
                        str(REALDATA / "photometry" / "radiance_mgflib_examp1.ies")], capture_output=True, check=True)
        (folder / "room.rad").write_text("void plastic wall 0 0 5 .5 .5 .5 0 0\n!genbox wall box 4 4 3 -i\n"
                                         "!xform -rz 90 -t 2 2 1.8 lum.rad\n")
        cases.append(("ies2rad room: genbox command, xform, brightdata table", lambda: read_scene(folder / "room.rad")))
    for label, call in cases:
        start = time.perf_counter()
        scene = call()
        print(f"{label}: {time.perf_counter() - start:.2f} s, {len(scene.triangles)} triangles")


if __name__ == "__main__":
    main()
