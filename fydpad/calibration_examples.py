"""Sample inputs for the calibration commands (``--example DIR``): what a lab measures,
made from a known device so a fit can be checked against it.

- IR pairs: three sensors whose curves are the paper's eq. (1) (Bianchi et al. 2015)
  stretched by 0.96, 1.00 and 1.05 in distance (parts differ), read at 40-300 mm every
  10 mm with 5 mV of noise;
- load cell: offset 12 000 counts, gain 1.05 x the CZL616C's nominal, three readings
  each under 0, 50, 100, 200, 500 and 700 g with 30 counts of noise;
- camera: 18 views of the default 7x5 ChArUco board (12 mm squares, 9 mm markers,
  DICT_5X5_100) held 90-130 mm in front of a wide-angle webcam (focal length 560 px,
  barrel distortion k1 -0.30), rendered by casting each pixel's ray through the lens
  model onto the tilted board (OpenCV's aruco module draws the board);
- softness: indenter presses of the simulated fabric (``fydpad.fabric.Fabric``, the
  station's one fabric model) at seven motor positions 0-1.2 rad, and of two specimens
  obeying F = lambda delta (paper IV-A) with the paper's S1 and S2 lambdas.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fydpad.fabric import Fabric
from vision.config import G_M_S2, NOMINAL_FORCE_GAIN_N_PER_COUNT
from vision.ir import distance_to_voltage_v

#: Each example sensor's distance stretch against eq. (1).
IR_STRETCH = (0.96, 1.00, 1.05)
IR_DISTANCES_MM = np.arange(40.0, 301.0, 10.0)
IR_NOISE_V = 0.005
FORCE_OFFSET_COUNTS = 12000.0
FORCE_GAIN_N_PER_COUNT = 1.05 * NOMINAL_FORCE_GAIN_N_PER_COUNT
FORCE_MASSES_G = (0.0, 50.0, 100.0, 200.0, 500.0, 700.0)
FORCE_NOISE_COUNTS = 30.0


def example_ir_volts(distance_mm: np.ndarray, sensor: int) -> np.ndarray:
    """The example sensor's noise-free voltage at ``distance_mm`` (the truth)."""
    return distance_to_voltage_v(np.asarray(distance_mm, float) / IR_STRETCH[sensor])


def write_ir_example(out_dir: Path, seed: int = 0) -> Path:
    """``ir_pairs.csv`` (distance_mm,v0,v1,v2) in ``out_dir``."""
    rng = np.random.default_rng(seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    d = IR_DISTANCES_MM
    volts = [example_ir_volts(d, i) + rng.normal(0, IR_NOISE_V, d.size) for i in range(3)]
    path = out_dir / "ir_pairs.csv"
    rows = ["distance_mm,v0,v1,v2"] + [
        f"{d[k]:.1f},{volts[0][k]:.4f},{volts[1][k]:.4f},{volts[2][k]:.4f}"
        for k in range(d.size)]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def write_force_example(out_dir: Path, seed: int = 0) -> Path:
    """``force_weights.csv`` (mass_g,raw) in ``out_dir``."""
    rng = np.random.default_rng(seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = ["mass_g,raw"]
    for mass_g in FORCE_MASSES_G:
        for _ in range(3):
            raw = (FORCE_OFFSET_COUNTS + mass_g * 1e-3 * G_M_S2 / FORCE_GAIN_N_PER_COUNT
                   + rng.normal(0, FORCE_NOISE_COUNTS))
            rows.append(f"{mass_g:g},{round(raw)}")
    path = out_dir / "force_weights.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


# --------------------------------------------------------------------------- camera

#: The example lens: camera matrix (px) and OpenCV distortion (k1, k2, p1, p2, k3).
LENS_K = np.array([[560.0, 0.0, 323.0], [0.0, 565.6, 236.0], [0.0, 0.0, 1.0]])
LENS_DIST = np.array([-0.30, 0.10, 0.0015, -0.001, 0.0])
LENS_SIZE = (640, 480)
CHARUCO_VIEWS = 18
CHARUCO_PX_PER_MM = 8.0


def _rotation(ax_deg: float, ay_deg: float, az_deg: float) -> np.ndarray:
    ax, ay, az = np.radians([ax_deg, ay_deg, az_deg])
    rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    return rz @ ry @ rx


def render_plane_view(texture: np.ndarray, px_per_mm: float, pose_r: np.ndarray,
                      pose_t: np.ndarray, k: np.ndarray = LENS_K,
                      dist: np.ndarray = LENS_DIST, size: tuple[int, int] = LENS_SIZE,
                      background: int = 128) -> np.ndarray:
    """What the lens (k, dist) sees of a flat printed ``texture`` (top-left corner at
    ``pose_t``, its x, y axes the columns of ``pose_r``, camera frame, mm): each pixel's
    ray (undistorted by the lens model) meets the plane, whose print is sampled there."""
    import cv2  # lazy: OpenCV costs start-up time to every other example and --help

    w, h = size
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pix = np.stack([uu.ravel(), vv.ravel()], axis=1).reshape(-1, 1, 2)
    norm = cv2.undistortPoints(pix, k, dist).reshape(-1, 2)
    rays = np.concatenate([norm, np.ones((norm.shape[0], 1))], axis=1)
    n = pose_r[:, 2]
    denom = rays @ n
    s = (pose_t @ n) / np.where(np.abs(denom) < 1e-9, 1e-9, denom)
    local = (s[:, None] * rays - pose_t) @ pose_r
    map_x = (local[:, 0] * px_per_mm - 0.5).reshape(h, w).astype(np.float32)
    map_y = (local[:, 1] * px_per_mm - 0.5).reshape(h, w).astype(np.float32)
    map_x[(s <= 0).reshape(h, w)] = -1.0
    return cv2.remap(texture, map_x, map_y, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=background)


def write_camera_example(out_dir: Path, seed: int = 0) -> Path:
    """``charuco/view_NN.png`` in ``out_dir``: the default board seen by the example lens
    at random poses (tilts up to 35 degrees) spread over the view; returns the folder."""
    # lazy: OpenCV (and vision.calibration, which loads it) cost start-up time to --help
    import cv2

    from vision.calibration import CharucoBoardSpec  # loads OpenCV too

    spec = CharucoBoardSpec()
    w_mm, h_mm = spec.squares_x * spec.square_mm, spec.squares_y * spec.square_mm
    board = spec.board().generateImage(
        (round(w_mm * CHARUCO_PX_PER_MM), round(h_mm * CHARUCO_PX_PER_MM)), marginSize=0)
    rng = np.random.default_rng(seed)
    folder = out_dir / "charuco"
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(CHARUCO_VIEWS):
        r = _rotation(*rng.uniform(-35, 35, 2), rng.uniform(-30, 30))
        centre = np.array([rng.uniform(-45, 45), rng.uniform(-35, 35), rng.uniform(90, 130)])
        t = centre - r @ np.array([w_mm / 2, h_mm / 2, 0.0])
        img = render_plane_view(board, CHARUCO_PX_PER_MM, r, t).astype(np.float64)
        img = np.clip(img + rng.normal(0.0, 2.0, img.shape), 0, 255).astype(np.uint8)
        cv2.imwrite(str(folder / f"view_{i:02d}.png"), img)
    return folder


# --------------------------------------------------------------------------- softness

SOFTNESS_THETAS_RAD = np.linspace(0.0, 1.2, 7)
SOFTNESS_DEPTHS_MM = np.linspace(0.5, 5.0, 10)
SOFTNESS_FORCE_NOISE_N = 0.02
SOFTNESS_DEPTH_NOISE_MM = 0.05
#: The specimens written, with their lambda (N/mm): the paper's S1 and S2 (IV-A).
SPECIMEN_LAMBDAS = {"S1": 0.88, "S2": 0.39}
SPECIMEN_DEPTHS_MM = np.linspace(0.5, 8.0, 16)


def _press(force_of, depths: np.ndarray, rng: np.random.Generator) -> tuple:
    """One indenter press down and up: the reported depth and load, with noise."""
    d = np.concatenate([depths, depths[::-1]])
    return (d + rng.normal(0.0, SOFTNESS_DEPTH_NOISE_MM, d.size),
            force_of(d) + rng.normal(0.0, SOFTNESS_FORCE_NOISE_N, d.size))


def write_softness_example(out_dir: Path, seed: int = 0, fabric: Fabric | None = None) -> Path:
    """``softness_indenter.csv`` (theta_rad,indentation_mm,force_n) in ``out_dir``: two
    presses of 0.5-5 mm at each motor position of the simulated fabric."""
    fabric = Fabric() if fabric is None else fabric
    rng = np.random.default_rng(seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = ["theta_rad,indentation_mm,force_n"]
    for theta in SOFTNESS_THETAS_RAD:
        tension = fabric.tension_n(fabric.stretch_mm(theta, theta))
        for _ in range(2):
            d, f = _press(lambda x, t=tension: fabric.force_n(x, t), SOFTNESS_DEPTHS_MM, rng)
            rows += [f"{theta:.4f},{a:.3f},{b:.4f}" for a, b in zip(d, f, strict=True)]
    path = out_dir / "softness_indenter.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def write_specimen_example(out_dir: Path, seed: int = 0) -> Path:
    """``specimen_S1.csv`` and ``specimen_S2.csv`` (indentation_mm,force_n) in
    ``out_dir``: two presses of 0.5-8 mm each; returns the first."""
    rng = np.random.default_rng(seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, lam in SPECIMEN_LAMBDAS.items():
        rows = ["indentation_mm,force_n"]
        for _ in range(2):
            d, f = _press(lambda x, lam=lam: lam * x, SPECIMEN_DEPTHS_MM, rng)
            rows += [f"{a:.3f},{b:.4f}" for a, b in zip(d, f, strict=True)]
        paths.append(out_dir / f"specimen_{name}.csv")
        paths[-1].write_text("\n".join(rows) + "\n", encoding="utf-8")
    return paths[0]
