"""ChArUco calibration accuracy on synthetic views rendered through known cameras.

Run: .venv/bin/python benchmarks/accuracy_charuco.py (from the repository root)
Uses the renderers and poses of tests/test_calibrate_geometry.py.
"""
import sys
import numpy as np
import cv2
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1]))
import tests.test_calibrate_geometry as T
from lsadphoto.calibrate.geometric import calibrate_geometry, parse_pattern

tex = T._charuco_texture()


def row(label, res, truth):
    p = res.projection
    n = [r["corners"] for r in res.per_image if r["used"]]
    print(f"| {label} | {len(n)}/{len(res.per_image)} | {min(n)}–{max(n)} | {res.rms_px:.3f} | "
          f"{p.fx:.2f} ({100 * (p.fx / truth.fx - 1):+.2f} %) | {p.fy:.2f} ({100 * (p.fy / truth.fy - 1):+.2f} %) | "
          f"{p.cx - truth.cx:+.2f} | {p.cy - truth.cy:+.2f} | {np.round(p.distortion, 4).tolist()} |")


print("| set | views used | corners/view | RMS [px] | fx [px] | fy [px] | Δcx [px] | Δcy [px] | distortion |")
print("|---|---|---|---|---|---|---|---|---|")
dirs = T._supersampled_directions(T.TRUE_PINHOLE, 3)
full = [T._render_charuco(dirs, r, c, tex) for r, c in T.PINHOLE_POSES]
row("pinhole, whole boards", calibrate_geometry(full, pattern=T.CHARUCO), T.TRUE_PINHOLE)
occ = [T._render_charuco(dirs, r, c, tex, hidden=h) for (r, c), h in zip(T.PINHOLE_POSES, T.OCCLUDERS)]
occ += [T._render_charuco(dirs, r, c, tex) for r, c in T.OFF_FRAME_POSES]
row("pinhole, partly hidden / out of frame", calibrate_geometry(occ, pattern=T.CHARUCO), T.TRUE_PINHOLE)
chess = [T._render(dirs, r, c) for r, c in T.PINHOLE_POSES]
row("pinhole, chessboard 9×6 inner (same poses)", calibrate_geometry(chess, pattern=T.PATTERN), T.TRUE_PINHOLE)
fdirs = T._supersampled_directions(T.TRUE_FISHEYE, 3)
fish = [T._render_charuco(fdirs, r, c, tex) for r, c in T.CHARUCO_FISHEYE_POSES]
row("fisheye, whole boards", calibrate_geometry(fish, pattern=T.CHARUCO, model="fisheye"), T.TRUE_FISHEYE)

# Corner accuracy of the detector against the projected truth (whole pinhole boards).
pat = parse_pattern(T.CHARUCO)
det = cv2.aruco.CharucoDetector(pat.opencv_board())
errs = []
for v, (r, c) in zip(full, T.PINHOLE_POSES):
    cc, ids, _, _ = det.detectBoard(v)
    ids = ids.ravel()
    R, t = T._board_pose(r, c)
    P = pat.object_points()[ids] @ R.T + t
    rr, ccol = T.TRUE_PINHOLE.project(P / np.linalg.norm(P, axis=1, keepdims=True))
    errs.append(np.hypot(cc.reshape(-1, 2)[:, 0] - ccol, cc.reshape(-1, 2)[:, 1] - rr))
e = np.concatenate(errs)
print(f"\nDetector corner error vs truth (pinhole, whole boards): mean {e.mean():.3f} px, "
      f"RMS {np.sqrt(np.mean(e ** 2)):.3f} px, max {e.max():.3f} px over {e.size} corners")

# Monte Carlo: scatter of the pinhole fit for these poses with 0.06 px Gaussian noise per axis.
obj = pat.object_points()
truth = []
for r, c in T.PINHOLE_POSES:
    R, t = T._board_pose(r, c)
    P = obj @ R.T + t
    rr, cc = T.TRUE_PINHOLE.project(P / np.linalg.norm(P, axis=1, keepdims=True))
    truth.append(np.stack([cc, rr], 1))
rng = np.random.default_rng(1)
out = []
for k in range(100):
    imgs = [(t + rng.normal(0, 0.06, t.shape)).astype(np.float32) for t in truth]
    _, K, d, _, _ = cv2.calibrateCamera([obj.astype(np.float32)] * len(imgs), imgs, (800, 600), np.eye(3),
                                        np.zeros(5), flags=0,
                                        criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12))
    out.append([K[0, 0], K[1, 1], K[0, 2], K[1, 2], d.ravel()[0]])
out = np.array(out)
print("Monte Carlo (100 fits, whole boards, 0.06 px/axis noise): σ fx {:.2f} px, σ fy {:.2f} px, "
      "σ cx {:.2f} px, σ cy {:.2f} px, σ k1 {:.4f}".format(*out.std(0)))
print("versions: OpenCV", cv2.__version__, "numpy", np.__version__)
