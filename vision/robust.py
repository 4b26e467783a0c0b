"""A contact tracker that survives real footage (see docs/tracking.md).

The paper's fixed grey-level threshold fails as soon as the light changes, the fabric
has a mark on it, or a hovering finger casts a shadow. This tracker measures each
pixel's darkness *relative to a model of the bare fabric* and accepts a dark region as a
contact only if it looks like a fingertip:

1. **Grey pyramid.** The ROI (cropped from the raw frame, flip folded into the
   coordinates) is converted to grey and reduced by ``pyramid_levels`` Gaussian
   pyramid steps: cheap, and the weave's texture is filtered out.
2. **Background model.** The bare fabric's brightness B, learned from the first frame and
   updated slowly wherever there is no contact (quickly where the image gets brighter,
   since a finger only darkens). Vignetting, uneven backlight and marks on the fabric are
   part of B, so they cancel in the ratio ``r = I / B``.
3. **Illumination.** Room light, flicker, auto-exposure and drifting daylight scale the
   whole image smoothly: a quadratic gain field G(u, v) is fitted to r over the pixels
   that are not dark (robust least squares on a grid), and the contrast is
   ``c = 1 - r / G`` (0 = bare fabric, 1 = black).
4. **Candidates.** Connected regions where c exceeds ``contrast_floor``; each one's peak
   contrast must exceed ``contrast_on`` to start a contact and ``contrast_off`` to keep
   one (hysteresis), its peak must not lie on the border of the view (the rest of the
   hand shadows the view from its edge), its core (pixels above ``core_fraction`` of the
   peak) must have a fingertip's area and shape, and its edge must be sharp: a contact
   presses the skin on the fabric, while a hovering finger's shadow is blurred by its
   distance (the ratio of the core's area to the area above a quarter of the peak).
5. **Centroid.** The contrast-weighted mean of the core's pixel centres, mapped back
   exactly through the pyramid to the flipped full frame, then to the workspace.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray


@dataclass
class RobustParams:
    """Settings of the robust tracker (contrasts are fractions of the bare fabric's brightness)."""

    pyramid_levels: int = 2
    #: Pixels darker than this contrast may belong to a candidate region.
    contrast_floor: float = 0.12
    #: Peak contrast needed to start a contact, and to keep one (hysteresis).
    contrast_on: float = 0.55
    contrast_off: float = 0.5
    #: The core of a region: pixels above this fraction of its peak contrast.
    core_fraction: float = 0.5
    #: Centroid weights: contrast minus this fraction of the peak, where positive.
    weight_floor_fraction: float = 0.3
    #: Fingertip contact area limits, in mm^2 of the workspace.
    min_area_mm2: float = 10.0
    max_area_mm2: float = 900.0
    #: A dark region this large (mm^2) that enters the view from its edge is the hand.
    max_edge_shadow_mm2: float = 600.0
    #: Largest ratio of the core's principal axes.
    max_elongation: float = 3.0
    #: Smallest ratio of the core's area to the area above a quarter of the peak.
    min_sharpness: float = 0.55
    #: Kept by hysteresis (peak below ``contrast_on``), a contact's share of its core
    #: above 90 % of its peak may be at most this (a hovering finger's shadow: ~0.65).
    max_hold_flatness: float = 0.5
    #: A light touch: its darkest spot stands out of its surroundings (white top-hat over
    #: prominence_size_mm) by this much to start a contact, and to keep one.
    prominence_on: float = 0.095
    prominence_off: float = 0.085
    prominence_size_mm: float = 9.0
    #: Background update rates per frame: towards darker (slow) and brighter (fast).
    bg_rate_darker: float = 0.02
    bg_rate_brighter: float = 0.25
    #: Pixels closer than this (mm) to the contact are not learned into the background.
    bg_guard_mm: float = 8.0
    #: Grid step (in pyramid pixels) of the samples the gain field is fitted on.
    gain_grid_step: int = 3
    #: Bootstrap without a stored background: the first frame's dark features narrower
    #: than this (mm) are filled from around them (a grey closing) to look for a finger
    #: already on the fabric.
    bootstrap_fill_mm: float = 36.0
    #: ... and a fingertip found there must be darkest within this many core radii of
    #: its centroid (a dried drop, darkest on its rim, is not; nor a flat ink dot).
    bootstrap_max_offcentre: float = 0.25


@dataclass(frozen=True, slots=True)
class RobustResult:
    """A contact found by :class:`RobustTracker`, in flipped full-frame pixels."""

    u_px: float
    v_px: float
    area_mm2: float
    peak_contrast: float
    sharpness: float
    prominence: float
    flatness: float = 0.0


class RobustTracker:
    """Background-relative contact detection over grey frames of one camera.

    Stateful (the background model and the contact hysteresis): one instance per camera
    stream; :meth:`reset` forgets the learned background (a stored one,
    :meth:`set_background`, is kept).
    """

    def __init__(
        self,
        roi_px: tuple[int, int, int, int],
        image_flip: str,
        workspace_mm: tuple[float, float],
        params: RobustParams | None = None,
    ):
        self.params = params or RobustParams()
        self.roi_px = roi_px
        self.image_flip = image_flip
        self.workspace_mm = workspace_mm
        self._shape: tuple[int, int] | None = None
        self._stored_bg: NDArray[np.uint8] | None = None
        self.reset()

    def reset(self) -> None:
        self._bg: NDArray[np.float32] | None = None
        self.in_contact = False

    def set_background(self, frame: NDArray[np.uint8]) -> None:
        """Start from a frame of the bare fabric (``fydpad calibrate background``) instead
        of bootstrapping from the first frame tracked; the same size as the frames."""
        self._stored_bg = self.grey_pyramid(frame)
        self.reset()

    # -- geometry ---------------------------------------------------------------

    def _raw_roi(self, frame_w: int, frame_h: int) -> tuple[int, int, int, int]:
        """The ROI in raw (unflipped) frame pixels."""
        x, y, w, h = self.roi_px
        if self.image_flip in ("horizontal", "both"):
            x = frame_w - x - w
        if self.image_flip in ("vertical", "both"):
            y = frame_h - y - h
        return x, y, w, h

    def _setup(self, small_shape: tuple[int, int]) -> None:
        p = self.params
        x, y, w, h = self.roi_px
        sh, sw = small_shape
        self._shape = small_shape
        # Pyramid pixel centre k maps to ROI pixel 2^L * (k + 0.5) - (2^L - 1) / 2 - 0.5 + 0.5:
        # each pyrDown puts output pixel k on input pixel 2k, i.e. c_in = 2 c_out - 0.5.
        scale = float(2**p.pyramid_levels)
        offset = -(scale - 1.0) / 2.0
        centres_u = (np.arange(sw) + 0.5) * scale + offset  # in raw-ROI pixels
        centres_v = (np.arange(sh) + 0.5) * scale + offset
        # Fold the flip in: flipped ROI coordinate = size - raw coordinate.
        if self.image_flip in ("horizontal", "both"):
            centres_u = w - centres_u
        if self.image_flip in ("vertical", "both"):
            centres_v = h - centres_v
        self._u_px = (x + centres_u).astype(np.float64)
        self._v_px = (y + centres_v).astype(np.float64)
        # Workspace mm per pyramid pixel: for areas and the background guard.
        self._cell_w_mm = self.workspace_mm[0] * scale / w
        self._cell_h_mm = self.workspace_mm[1] * scale / h
        self._cell_area_mm2 = self._cell_w_mm * self._cell_h_mm
        # Gain-field design matrix on a grid: 1, u, v, u^2, uv, v^2 (normalised coordinates).
        step = p.gain_grid_step
        gv, gu = np.mgrid[step // 2 : sh : step, step // 2 : sw : step]
        uu = (np.arange(sw, dtype=np.float32) / sw - 0.5) * 2
        vv = (np.arange(sh, dtype=np.float32) / sh - 0.5) * 2
        U, V = np.meshgrid(uu, vv)
        self._basis_full = np.stack([np.ones_like(U), U, V, U * U, U * V, V * V]).reshape(6, -1)
        self._grid_flat = (gv.ravel() * sw + gu.ravel()).astype(np.intp)
        basis_t = self._basis_full[:, self._grid_flat].astype(np.float64)  # 6 x samples
        self._basis_grid_t = basis_t
        # Each sample's outer product b b^T (its 21 distinct entries) as a column: the
        # normal matrix of the kept samples is then one matrix-vector product with their
        # 0/1 weights.
        self._upper = np.triu_indices(6)
        self._lower = self._upper[::-1]
        self._outer_t = basis_t[self._upper[0]] * basis_t[self._upper[1]]
        self._normal = np.empty((6, 6))
        self._ridge = 1e-9 * np.eye(6)
        self._gain = np.empty((sh, sw), np.float32)
        # Top-hat structuring element: an ellipse of prominence_size_mm across.
        kw = 2 * round(p.prominence_size_mm / self._cell_w_mm / 2) + 1
        kh = 2 * round(p.prominence_size_mm / self._cell_h_mm / 2) + 1
        self._tophat_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (kw, kh))
        self._ring_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
        self._contrast = np.empty((sh, sw), np.float32)
        self._ratio = np.empty((sh, sw), np.float32)
        self._img = np.empty((sh, sw), np.float32)
        self._cols = np.arange(sw, dtype=np.float64)
        self._rows = np.arange(sh, dtype=np.float64)
        # Per-frame buffers, allocated once.
        self._dark = np.zeros((sh, sw), bool)
        self._fast = np.empty((sh, sw), np.float32)
        self._brighter = np.empty((sh, sw), np.uint8)
        self._target = np.empty((sh, sw), np.float32)
        self._rate = np.empty((sh, sw), np.float32)
        gw = 2 * int(np.ceil(p.bg_guard_mm / self._cell_w_mm / 2)) + 1
        gh = 2 * int(np.ceil(p.bg_guard_mm / self._cell_h_mm / 2)) + 1
        self._guard_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (gw, gh))
        #: Box around the dark pixels of the last frame (x, y, w, h; w = 0: none).
        self._dark_box = (0, 0, 0, 0)

    # -- per frame --------------------------------------------------------------

    def grey_pyramid(self, frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
        fh, fw = frame.shape[:2]
        x, y, w, h = self._raw_roi(fw, fh)
        if x < 0 or y < 0 or x + w > fw or y + h > fh:
            raise ValueError(f"ROI {list(self.roi_px)} lies outside the {fw}x{fh} frame")
        roi = frame[y : y + h, x : x + w]
        grey = cv2.cvtColor(roi, cv2.COLOR_BGR2GRAY) if roi.ndim == 3 else roi
        for _ in range(self.params.pyramid_levels):
            grey = cv2.pyrDown(grey)
        return grey

    def process(self, frame: NDArray[np.uint8]) -> RobustResult | None:
        small = self.grey_pyramid(frame)
        if self._shape != small.shape:
            self._setup(small.shape)
            self._bg = None
        img = self._img
        np.copyto(img, cv2.max(small, 1))  # no zero grey level: I / B stays finite
        if self._bg is None:
            if self._stored_bg is not None and self._stored_bg.shape == small.shape:
                self._bg = cv2.max(self._stored_bg, 1).astype(np.float32)
            else:
                self._bg = self._bootstrap(img)
        result = self._detect(img)
        self._update_background(img, result)
        return result

    def _bootstrap(self, img: NDArray[np.float32]) -> NDArray[np.float32]:
        """The background from the first frame, without learning a finger already on it.

        The first frame is the background (marks, vignetting and all) except where a
        finger may be: a grey closing over ``bootstrap_fill_mm`` (a local maximum, then
        a minimum) fills every dark feature narrower than that from the fabric around
        it; the frame is then looked at against that filled background with the
        tracker's own checks, and where they find a fingertip that peaks in its middle,
        its dark region (grown by ``bg_guard_mm``) takes the filled value. Marks and
        shadows that do not pass as such a fingertip stay in the background as they
        are."""
        p = self.params
        kw = 2 * round(p.bootstrap_fill_mm / self._cell_w_mm / 2) + 1
        kh = 2 * round(p.bootstrap_fill_mm / self._cell_h_mm / 2) + 1
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (kw, kh))
        filled = cv2.morphologyEx(img, cv2.MORPH_CLOSE, kernel, borderType=cv2.BORDER_REPLICATE)
        self._bg = filled
        found = self._detect(img)
        self.in_contact = False  # the first frame's answer is the next call's
        bg = img.copy()
        # A fingertip pressed on the fabric peaks in its middle (darkest near its
        # centroid, little of its core near the peak: the test of a contact kept by
        # hysteresis); a mark that passes the other checks does not (a dried drop is
        # darkest on its rim, an ink dot is flat-topped): it stays in the background.
        if (found is not None and self._best_offcentre <= p.bootstrap_max_offcentre
                and found.flatness <= p.max_hold_flatness):
            x0, y0, bw, bh = self._best_box
            region = np.zeros(self._shape, np.uint8)
            region[y0 : y0 + bh, x0 : x0 + bw] = self._dark[y0 : y0 + bh, x0 : x0 + bw]
            region = cv2.dilate(region, self._guard_kernel)
            np.copyto(bg, filled, where=region.view(bool))
        return bg

    def _fit_gain(self, ratio: NDArray[np.float32]) -> NDArray[np.float32]:
        """A smooth gain field fitted to ``I / B`` over pixels that are not dark."""
        samples = ratio.ravel().take(self._grid_flat).astype(np.float64)
        # First a band around the median: a finger or a shadow is darker, a dark thing
        # learned into the background that has gone (a palm resting at the start)
        # brighter; then a band around the fit.
        med = _median(samples)
        lo, hi = med * 0.85, med * 1.15
        for i in range(3):
            # Least squares by the 6x6 normal equations over the samples kept (the rest
            # weighted 0: cheaper than copying the kept rows out).
            keep = ((samples > lo) & (samples < hi)).astype(np.float64)
            normal = self._normal
            normal[self._upper] = normal[self._lower] = self._outer_t @ keep
            normal += self._ridge
            rhs = self._basis_grid_t @ (samples * keep)
            # cv2.solve: the same LU with partial pivoting as np.linalg.solve, without
            # its ~20 us of Python-side checks per call.
            _, coef = cv2.solve(normal, rhs[:, None], flags=cv2.DECOMP_LU)
            coef = coef.ravel()
            if i < 2:
                # Drop samples well below the fit (a finger, a shadow) and well above it
                # (a dark thing learned into the background that has gone: a palm that
                # rested at the start), and refit.
                fit = coef @ self._basis_grid_t
                lo = fit * 0.9
                hi = fit * 1.12
        gain = self._gain
        np.matmul(coef.astype(np.float32), self._basis_full, out=gain.reshape(-1))
        cv2.max(gain, 1e-3, dst=gain)
        return gain

    def _detect(self, img: NDArray[np.float32]) -> RobustResult | None:
        p = self.params
        ratio = np.divide(img, self._bg, out=self._ratio)
        gain = self._fit_gain(ratio)
        contrast = self._contrast
        np.divide(ratio, gain, out=contrast)
        np.subtract(1.0, contrast, out=contrast)
        np.greater(contrast, p.contrast_floor, out=self._dark)
        mask = self._dark.view(np.uint8)
        # Label only the box around the dark pixels (mostly a small part of the view):
        # the same regions as labelling the whole view, at a fraction of the cost.
        self._dark_box = bx, by, bbw, bbh = cv2.boundingRect(mask)
        if bbw == 0:
            self.in_contact = False
            return None
        # Labels without OpenCV's statistics: they cost several times the labelling;
        # the few regions get their area and box below.
        n, labels = cv2.connectedComponents(mask[by : by + bbh, bx : bx + bbw], connectivity=8)
        sh, sw = self._shape
        best: RobustResult | None = None
        best_score = 0.0
        min_cells = p.min_area_mm2 / self._cell_area_mm2
        for i in range(1, n):
            label = labels == i
            area = np.count_nonzero(label)
            if area < min_cells:
                continue
            lx, ly, bw, bh = cv2.boundingRect(label.view(np.uint8))
            x0, y0 = lx + bx, ly + by  # in the view
            sub = contrast[y0 : y0 + bh, x0 : x0 + bw]
            inside = label[ly : ly + bh, lx : lx + bw]
            region = np.where(inside, sub, 0.0)
            peak_idx = int(np.argmax(region))
            peak = float(region.flat[peak_idx])
            py, px = divmod(peak_idx, bw)
            py += y0
            px += x0
            if px == 0 or py == 0 or px == sw - 1 or py == sh - 1:
                continue  # darkest at the edge of the view: a hand outside it, not a contact
            touches_edge = x0 == 0 or y0 == 0 or x0 + bw == sw or y0 + bh == sh
            if touches_edge and area * self._cell_area_mm2 > p.max_edge_shadow_mm2:
                continue  # a large shadow coming in from the edge: the rest of the hand
            core = region > peak * p.core_fraction
            core_cells = int(np.count_nonzero(core))
            core_area = core_cells * self._cell_area_mm2
            if not p.min_area_mm2 <= core_area <= p.max_area_mm2:
                continue
            sharpness = core_cells / max(1, int(np.count_nonzero(region > peak * 0.25)))
            flatness = int(np.count_nonzero(region > peak * 0.9)) / max(1, core_cells)
            # How far the darkest spot stands out of its surroundings (white top-hat):
            # a light touch is a small dark core on the fingertip's shadow; a hovering
            # finger's shadow is a broad plateau that the opening keeps whole.
            tophat = self._tophat(contrast, x0, y0, bw, bh)
            prominence = cv2.minMaxLoc(tophat, inside.view(np.uint8))[1]
            sharp = sharpness >= p.min_sharpness
            starts = (peak >= p.contrast_on and sharp) or prominence >= p.prominence_on
            # Kept by hysteresis alone, a contact must still peak in its middle: a
            # release leaves a shrinking dark centre, a lifted finger a flat-topped
            # shadow as dark and as sharp-edged as a light contact.
            kept = (self.in_contact and flatness <= p.max_hold_flatness
                    and ((peak >= p.contrast_off and sharp)
                         or prominence >= p.prominence_off))
            if not (starts or kept):
                continue
            # Soft weights (contrast above a floor) rather than the hard core: a hard cut
            # jumps by whole pyramid cells as the edge crosses them. The floor sits above
            # the shadow the contact stands out of (its level on a ring just outside the
            # core): the fingertip's shadow is not centred on the contact and would pull
            # the centroid towards the fingertip's end.
            # The core (above half the peak) may take in a dark shadow around a contact;
            # re-cut it halfway between the shadow's level and the peak, and look again.
            shadow = 0.0
            cut = core
            for _ in range(3):
                cut8 = cut.view(np.uint8)
                ring = np.greater(cv2.dilate(cut8, self._ring_kernel), cut8)  # dilated, not cut
                ring &= inside
                ring_values = region[ring]
                if not ring_values.size:
                    break
                level = _median(ring_values)
                if level <= shadow + 0.01:
                    break
                shadow = level
                cut = region > shadow + 0.5 * (peak - shadow)
            f = p.weight_floor_fraction
            w = np.subtract(region, np.float32(max(peak * f, shadow + f * (peak - shadow))))
            np.maximum(w, 0.0, out=w)
            mom = _moments(w)
            total = mom["m00"]
            cu = x0 + mom["m10"] / total
            cv_ = y0 + mom["m01"] / total
            if _elongation(mom) > p.max_elongation:
                continue
            # Of several candidates, the darkest and most prominent is the fingertip.
            score = peak + prominence
            if score > best_score:
                best_score = score
                best = RobustResult(
                    u_px=float(np.interp(cu, self._cols, self._u_px)),
                    v_px=float(np.interp(cv_, self._rows, self._v_px)),
                    area_mm2=core_area,
                    peak_contrast=peak,
                    sharpness=sharpness,
                    prominence=prominence,
                    flatness=flatness,
                )
                self._best_box = (x0, y0, bw, bh)
                # Where its darkest cell lies from its centroid, in core radii.
                self._best_offcentre = float(np.hypot(px - cu, py - cv_)) / max(
                    np.sqrt(core_cells / np.pi), 1.0)
        self.in_contact = best is not None
        return best

    def _tophat(self, contrast: NDArray[np.float32], x0: int, y0: int, bw: int, bh: int
                ) -> NDArray[np.float32]:
        """White top-hat of the contrast over one region's box, equal there to the whole
        image's (``cv2.morphologyEx(MORPH_TOPHAT)`` with replicated borders): the contrast
        less its opening, an erosion then a dilation by the kernel."""
        sh, sw = contrast.shape
        kernel = self._tophat_kernel
        ry, rx = kernel.shape[0] // 2, kernel.shape[1] // 2
        # The dilation at the box reads the erosion up to a radius around it, which reads
        # the contrast up to a radius further: each is computed only where it is read.
        ya, yb = max(0, y0 - 2 * ry), min(sh, y0 + bh + 2 * ry)
        xa, xb = max(0, x0 - 2 * rx), min(sw, x0 + bw + 2 * rx)
        eroded = cv2.erode(contrast[ya:yb, xa:xb], kernel, borderType=cv2.BORDER_REPLICATE)
        ea, eb = max(0, y0 - ry), min(sh, y0 + bh + ry)
        fa, fb = max(0, x0 - rx), min(sw, x0 + bw + rx)
        opened = cv2.dilate(eroded[ea - ya : eb - ya, fa - xa : fb - xa], kernel,
                            borderType=cv2.BORDER_REPLICATE)
        return contrast[y0 : y0 + bh, x0 : x0 + bw] - opened[y0 - ea : y0 - ea + bh,
                                                             x0 - fa : x0 - fa + bw]

    def _update_background(self, img: NDArray[np.float32], result: RobustResult | None) -> None:
        p = self.params
        # Learn the fabric under the current light: divide the light back out first.
        target = np.divide(img, self._gain, out=self._target)
        diff = np.subtract(target, self._bg, out=target)  # > 0: brighter than B
        # Nothing dark enough to be a candidate is learned darker, contact or not: a
        # finger hovering still would otherwise sink into the background, and when it
        # moves on, its ghost carves a sharp crescent out of its shadow that passes for
        # a light touch. Marks present from the first frame are in the background anyway.
        rate = self._rate
        rate.fill(p.bg_rate_darker)
        bx, by, bbw, bbh = self._dark_box
        if bbw:
            # Grown by the guard kernel only around the dark pixels' box: outside it
            # the dilation of the whole view is 0.
            sh, sw = self._shape
            ry, rx = (k // 2 for k in self._guard_kernel.shape)
            ya, yb = max(0, by - ry), min(sh, by + bbh + ry)
            xa, xb = max(0, bx - rx), min(sw, bx + bbw + rx)
            grown = cv2.dilate(self._dark.view(np.uint8)[ya:yb, xa:xb], self._guard_kernel)
            rate[ya:yb, xa:xb][grown.view(bool)] = 0.0
        # Quickly where the fabric got brighter, guard or not (a finger only darkens);
        # cv2's masked copy: a masked np.copyto costs several times more.
        cv2.compare(diff, 0.0, cv2.CMP_GT, dst=self._brighter)
        self._fast.fill(p.bg_rate_brighter)
        cv2.copyTo(self._fast, self._brighter, rate)
        if result is not None:
            x0, y0, bw, bh = self._best_box
            gx = int(np.ceil(p.bg_guard_mm / self._cell_w_mm))
            gy = int(np.ceil(p.bg_guard_mm / self._cell_h_mm))
            rate[max(0, y0 - gy) : y0 + bh + gy, max(0, x0 - gx) : x0 + bw + gx] = 0.0
        diff *= rate
        self._bg += diff


def _median(a: NDArray) -> float:
    """The median of a non-empty 1-D array by partition (np.median's generality costs
    more than the partition itself on the per-frame path)."""
    mid = a.size // 2
    if a.size % 2:
        return float(np.partition(a, mid)[mid])
    part = np.partition(a, (mid - 1, mid))
    return 0.5 * float(part[mid - 1] + part[mid])


def _moments(w: NDArray[np.float32]) -> dict[str, float]:
    """``cv2.moments`` of a weight image (accumulated in double precision).

    OpenCV reads a 2-column single-channel array as a list of points, so a region two
    cells wide gets a column of zero weights first (which changes no moment)."""
    if w.shape[1] == 2:
        w = np.pad(w, ((0, 0), (0, 1)))
    return cv2.moments(w)


def _elongation(mom: dict[str, float]) -> float:
    """Ratio of the principal axes of a weighted region (1 for a disc), from its
    ``cv2.moments``: the eigenvalues of the weighted covariance (mu20, mu11; mu11, mu02)."""
    total = mom["m00"]
    suu = mom["mu20"] / total
    svv = mom["mu02"] / total
    suv = mom["mu11"] / total
    tr = suu + svv
    det = suu * svv - suv * suv
    disc = max(tr * tr / 4 - det, 0.0) ** 0.5
    small = tr / 2 - disc
    big = tr / 2 + disc
    return float(np.sqrt(big / small)) if small > 1e-12 else float("inf")
