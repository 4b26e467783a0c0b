"""Image-workspace geometry of docs/recording_format.md."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from vision.mapping import flip_frame, flip_point, roi_to_workspace, workspace_to_roi

ROI = (24, 22, 592, 414)
WS = (100.0, 70.0)


def test_roi_corners_are_the_workspace_corners():
    x, y = roi_to_workspace([24, 616, 24, 616], [22, 22, 436, 436], ROI, WS)
    assert x.tolist() == [-50.0, 50.0, -50.0, 50.0]
    assert y.tolist() == [35.0, 35.0, -35.0, -35.0]  # top of the image is away from the user


def test_a_processing_cell_is_not_square():
    # At 160 x 120 a cell is 0.625 x 0.583 mm (docs/recording_format.md).
    assert WS[0] / 160 == pytest.approx(0.625)
    assert WS[1] / 120 == pytest.approx(0.5833, abs=1e-4)


@given(st.floats(-60, 60), st.floats(-40, 40))
def test_round_trip(x_mm, y_mm):
    u, v = workspace_to_roi(x_mm, y_mm, ROI, WS)
    x2, y2 = roi_to_workspace(u, v, ROI, WS)
    assert x2 == pytest.approx(x_mm, abs=1e-9) and y2 == pytest.approx(y_mm, abs=1e-9)


@given(st.sampled_from(["none", "horizontal", "vertical", "both"]),
       st.floats(0, 640), st.floats(0, 480))
def test_flip_point_is_its_own_inverse(flip, u, v):
    assert flip_point(*flip_point(u, v, flip, (640, 480)), flip, (640, 480)) == pytest.approx(
        (u, v))


@pytest.mark.parametrize("flip", ["none", "horizontal", "vertical", "both"])
def test_flip_point_follows_flip_frame(flip):
    img = np.zeros((48, 64), np.uint8)
    img[10, 5] = 255  # pixel (col 5, row 10), centre (5.5, 10.5)
    j, i = np.argwhere(flip_frame(img, flip))[0]
    assert flip_point(5.5, 10.5, flip, (64, 48)) == (i + 0.5, j + 0.5)


def test_unknown_flip():
    with pytest.raises(ValueError, match="image_flip"):
        flip_frame(np.zeros((2, 2), np.uint8), "diagonal")
