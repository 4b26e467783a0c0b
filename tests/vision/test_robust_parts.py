"""Parts of the robust tracker that were rewritten for speed give what the plain
computation gives: the region moments (``cv2.moments``, which reads a two-column array as
a list of points) and the top-hat computed on a region's box only."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vision.robust import RobustTracker, _moments


@pytest.mark.parametrize("shape", [(1, 1), (1, 2), (5, 2), (2, 5), (5, 3), (7, 1), (40, 33)])
def test_moments_match_numpy(shape):
    w = np.random.default_rng(3).random(shape).astype(np.float32)
    m = _moments(w)
    vv, uu = np.indices(shape)
    total = float(w.sum(dtype=np.float64))
    cu = float((w * uu).sum(dtype=np.float64)) / total
    cv_ = float((w * vv).sum(dtype=np.float64)) / total
    assert m["m00"] == pytest.approx(total, rel=1e-6)
    assert m["m10"] / m["m00"] == pytest.approx(cu, rel=1e-6)
    assert m["m01"] / m["m00"] == pytest.approx(cv_, rel=1e-6)
    assert m["mu20"] == pytest.approx(float((w * (uu - cu) ** 2).sum()), rel=1e-5, abs=1e-9)
    assert m["mu02"] == pytest.approx(float((w * (vv - cv_) ** 2).sum()), rel=1e-5, abs=1e-9)
    assert m["mu11"] == pytest.approx(float((w * (uu - cu) * (vv - cv_)).sum()),
                                      rel=1e-5, abs=1e-6)


def test_box_tophat_equals_whole_image_tophat():
    t = RobustTracker((24, 22, 592, 414), "horizontal", (100.0, 70.0))
    t._setup((104, 148))
    rng = np.random.default_rng(1)
    for _ in range(300):
        c = cv2.GaussianBlur(rng.random((104, 148)).astype(np.float32), (0, 0),
                             rng.uniform(0.5, 4.0))
        whole = cv2.morphologyEx(c, cv2.MORPH_TOPHAT, t._tophat_kernel,
                                 borderType=cv2.BORDER_REPLICATE)
        bw, bh = (int(v) for v in rng.integers(1, 60, 2))
        x0 = int(rng.integers(0, 148 - bw + 1))
        y0 = int(rng.integers(0, 104 - bh + 1))
        np.testing.assert_array_equal(t._tophat(c, x0, y0, bw, bh),
                                      whole[y0 : y0 + bh, x0 : x0 + bw])


def test_a_stored_background_is_used_and_kept_across_reset():
    """``set_background`` with a bare-fabric frame: a finger present in the first frame
    tracked is found against it, and ``reset`` forgets what was learned, not it."""
    from fydpad.synth import SynthConfig, SyntheticPad
    from fydpad.synth.trajectory import start_time_s
    from vision.contact import ContactTracker

    long = SyntheticPad(SynthConfig(trajectory="walk", seconds=6.0, seed=5))
    pad = SyntheticPad(SynthConfig(trajectory="walk", seconds=1.0, seed=5,
                                   start_s=start_time_s(long.path, "down_still")))
    bare = long.frame(0)  # the finger 45 mm above the fabric
    cfg = pad.cfg
    t = ContactTracker(roi_px=cfg.roi_px, workspace_mm=cfg.workspace_mm,
                       image_flip=cfg.image_flip)
    t._robust.set_background(bare)
    for _ in range(2):
        r = t.process(pad.frame(0))
        truth = pad.truth(0)
        assert r is not None and truth.contact
        assert np.hypot(r.x_mm - truth.x_mm, r.y_mm - truth.y_mm) < 0.3
        t.reset()
    assert t._robust._stored_bg is not None
