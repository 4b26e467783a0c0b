"""The station's web view: an aiohttp server in a thread with its own asyncio loop.

It never slows the station: it only reads ``station.snapshot.latest()`` and
``station.live_stats`` (reference reads), keeps the plotted samples in a bounded deque
(the oldest dropped), encodes a JPEG only when a browser asks for one (at most 10 per
second) and writes settings by swapping the tracker reference and writing the control
record. The 1 kHz render loop runs in another process.
"""

from __future__ import annotations

import asyncio
import collections
import dataclasses
import ipaddress
import json
import math
import secrets
import threading
import time
from pathlib import Path

import cv2
from aiohttp import web

from fydpad.annotate import annotate_frame
from fydpad.config import save_config
from fydpad.web.calibration import PressCollector
from fydpad.web.experiment import (
    PAPER_STIMULI,
    ExperimentError,
    ExperimentSession,
    Stimulus,
    plot_png,
    report,
)
from fydpad.web.indentation_guide import indentation_guide
from fydpad.web.staircase import StaircaseSession
from vision.calibration import CalibratedMapping, CalibrationError
from vision.strict_json import finite

STATIC = Path(__file__).parent / "static"
#: Samples kept for the plots (10 s at up to 60 fps, plus slack).
SAMPLE_CAPACITY = 1200
JPEG_MIN_INTERVAL_S = 0.1  # <= 10 fps
FLIPS = ("none", "horizontal", "vertical", "both")
#: The response header of /api/frame.jpg carrying the shown frame's numbers.
FRAME_HEADER = "X-Fydpad-Frame"



def _json_response(data: object, status: int = 200) -> web.Response:
    """A JSON answer the page's JSON.parse accepts: NaN and inf (no value yet) as null."""
    return web.json_response(data, status=status,
                             dumps=lambda obj: json.dumps(finite(obj), allow_nan=False))

def _num(v) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def frame_numbers(view) -> dict:
    """The numbers the overlay of ``view``'s image draws, and the readout under it shows:
    one frame's (None where there is no value)."""
    s, c = view.state, view.contact
    return {"index": view.frame_index, "t_s": _num(s.t_s), "contact": c is not None,
            "x_mm": _num(c.x_mm) if c else None, "y_mm": _num(c.y_mm) if c else None,
            "indentation_mm": _num(s.indentation_mm), "force_n": _num(s.force_n)}


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def friction_slot(render) -> tuple[int | None, str]:
    """The render process's slot (``[texture, *textures]``) of the friction model the
    staircase applies b to: ``--texture`` when it is one (the model compared with the
    real sample), else the first among the stimuli's; (None, why not) when none is."""
    # lazy: the texture library (SciPy) loads only when a staircase needs a friction model
    from fydpad.errors import UserError
    from fydpad.texture.families import model_kind, read_model_json, split_spec

    if render is None or (render.motors == "none" and render.chain is None):
        return None, ("the staircase sets b of a rendered friction model, but this station "
                      "drives no motors: start it with --motors sim|qb --texture "
                      "friction:MODEL.json")
    specs = [render.texture, *render.textures]
    for i, spec in enumerate(specs):
        if spec is None:
            continue
        kind, path = split_spec(spec)
        if kind is None:
            try:
                kind = model_kind(read_model_json(path))
            except UserError:  # the render process reports an unreadable model itself
                continue
        if kind == "friction":
            return i, spec
    given = render.texture or "none"
    return None, (f"the staircase sets b of a rendered friction model, but the station "
                  f"renders none (--texture: {given}): start it with --texture "
                  "friction:MODEL.json")


class StationStimulus:
    """Presents an experiment stimulus on the station through the render process's
    control record: its stiffness, and its texture model selected by index among those
    the render process loaded at start (``RenderSpec.texture``, slot 0, and
    ``RenderSpec.textures``; not loaded: texture off). ``texture_hook(stimulus)``, if
    given, is called too."""

    def __init__(self, station, texture_hook=None):
        self.station = station
        self.texture_hook = texture_hook
        self.current: Stimulus | None = None
        render = getattr(station.options, "render", None)
        #: Model spec -> its index in the render process ([texture, *textures]); a model
        #: loaded twice keeps its first slot (--texture: 0).
        specs = [getattr(render, "texture", None), *getattr(render, "textures", ())]
        self.texture_index: dict[str, int] = {}
        for i, t in enumerate(specs):
            if t is not None:
                self.texture_index.setdefault(t, i)

    def __call__(self, stim: Stimulus | None) -> None:
        self.current = stim
        if stim is None:  # session complete: vibration and texture off
            self.station.set_control(vibration_enabled=0.0, texture_index=-1.0)
        else:
            self.station.set_control(stiffness_n_per_mm=stim.stiffness_n_per_mm,
                                     vibration_enabled=1.0,
                                     texture_index=self.texture_index.get(stim.texture, -1))
        if self.texture_hook is not None:
            self.texture_hook(stim)

    def rendered(self, stim: Stimulus | None) -> bool:
        """Whether the station renders this stimulus's texture (else it is only shown)."""
        return stim is not None and stim.texture in self.texture_index


class WebView:
    """The application's state and handlers (runs in the web thread)."""

    def __init__(self, station, config, config_path, results_dir, token, texture_hook=None,
                 stimuli: tuple[Stimulus, ...] | list[Stimulus] = PAPER_STIMULI):
        self.station = station
        self.stimuli = list(stimuli)
        self.config = config
        self.config_path = Path(config_path) if config_path else None
        self.results_dir = Path(results_dir)
        self.token = token
        self.samples: collections.deque = collections.deque(maxlen=SAMPLE_CAPACITY)
        self._last_index = -1
        #: (encoded at, frame index, JPEG, that frame's numbers as JSON): one frame's.
        self._jpeg: tuple[float, int, bytes, str] | None = None
        self.jpeg_encoded = 0
        self.session: ExperimentSession | None = None
        self.stimulus = StationStimulus(station, texture_hook)
        self.texture_name = getattr(getattr(station.options, "render", None), "texture", None)
        #: The render slot of the friction model the staircase sets b of; else None and
        #: ``friction_model`` says why.
        self.friction_slot, self.friction_model = friction_slot(
            getattr(station.options, "render", None))
        self.staircase: StaircaseSession | None = None
        self.calibration: PressCollector | None = None
        self._calibration_fit: dict | None = None

    # -- sampling -------------------------------------------------------------------------

    async def sampler(self) -> None:
        """Copy each new finger state into the bounded deque (50 Hz polling)."""
        while True:
            view = self.station.snapshot.latest()
            if view is not None and view.frame_index != self._last_index:
                self._last_index = view.frame_index
                s = view.state
                self.samples.append((view.frame_index, s.t_s, bool(s.contact), _num(s.x_mm),
                                     _num(s.y_mm), _num(s.indentation_mm), _num(s.force_n)))
                cal, c = self.calibration, view.contact
                if cal is not None:
                    cal.feed(s.t_s, c is not None, c.u_px if c else math.nan,
                             c.v_px if c else math.nan)
            await asyncio.sleep(0.02)

    # -- auth -----------------------------------------------------------------------------

    @web.middleware
    async def auth(self, request: web.Request, handler):
        if self.token is None:
            return await handler(request)
        given = (request.query.get("token") or request.cookies.get("fydpad_token")
                 or request.headers.get("Authorization", "").removeprefix("Bearer ").strip())
        if not given or not secrets.compare_digest(given, self.token):
            return web.Response(status=401, text="401: this station's web view needs its "
                                "token (printed when the station started): add ?token=...")
        resp = await handler(request)
        if request.query.get("token"):
            resp.set_cookie("fydpad_token", self.token, httponly=True, samesite="Strict")
        return resp

    # -- pages ----------------------------------------------------------------------------

    async def index(self, request):
        return web.FileResponse(STATIC / "index.html")

    async def experiment_page(self, request):
        return web.FileResponse(STATIC / "experiment.html")

    async def calibrate_page(self, request):
        return web.FileResponse(STATIC / "calibrate.html")

    # -- live -----------------------------------------------------------------------------

    def settings(self) -> dict:
        tr = self.station.tracker
        control = self.station.control.read()[1]
        return {
            "roi_px": list(tr.roi_px), "threshold": tr.threshold, "image_flip": tr.image_flip,
            "method": tr.method, "workspace_mm": list(tr.workspace_mm),
            "vibration_gain": _num(control[0]), "stiffness_n_per_mm": _num(control[1]),
            "vibration_enabled": bool(control[2]), "texture": self.texture_name,
            "texture_index": _num(control[4]), "friction_b_v": _num(control[5]),
            "config_path": str(self.config_path) if self.config_path else None,
        }

    async def state(self, request):
        since = int(request.query.get("since", -1))
        samples = [s for s in list(self.samples) if s[0] > since]
        view = self.station.snapshot.latest()
        frame = None
        if view is not None:
            h, w = view.raw_frame.shape[:2]
            frame = {"index": view.frame_index, "width": w, "height": h,
                     "u_px": view.contact.u_px if view.contact else None,
                     "v_px": view.contact.v_px if view.contact else None}
        stats = dict(self.station.live_stats)
        return _json_response({
            "frame": frame,
            "samples": samples,
            "stats": {k: stats.get(k) for k in ("render", "vision", "frame_to_command_ms")},
            # What the render process says it renders (texture model, switches, b).
            "texture": stats.get("texture"),
            # The tele-operation link posts {"mae_mm": [...], ...} here when it lands.
            "link": stats.get("link"),
            "operator_hold": bool(getattr(self.station, "operator_hold", False)),
            "settings": self.settings(),
            "stimulus": dataclasses.asdict(self.stimulus.current)
            if self.stimulus.current else None,
            "stimulus_rendered": self.stimulus.rendered(self.stimulus.current),
            "jpeg_encoded": self.jpeg_encoded,
        })

    async def frame_jpg(self, request):
        """The annotated camera image of one frame, and that frame's numbers in the
        ``X-Fydpad-Frame`` header (JSON): the page writes its readout from the header of
        the image it shows, so the overlay and the text always belong to one frame."""
        now = time.monotonic()
        view = self.station.snapshot.latest()
        if view is None:
            return web.Response(status=204)
        cached = self._jpeg
        if cached is None or (cached[1] != view.frame_index
                              and now - cached[0] >= JPEG_MIN_INTERVAL_S):
            tr = self.station.tracker
            img = annotate_frame(view.raw_frame, tr.image_flip, tr.roi_px, view.contact,
                                 label=f"frame {view.frame_index}")
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 80])
            if not ok:
                return web.Response(status=500, text="JPEG encoding failed")
            cached = self._jpeg = (now, view.frame_index, buf.tobytes(),
                                   json.dumps(frame_numbers(view), allow_nan=False))
            self.jpeg_encoded += 1
        return web.Response(body=cached[2], content_type="image/jpeg",
                            headers={"Cache-Control": "no-store", FRAME_HEADER: cached[3]})

    # -- setup ----------------------------------------------------------------------------

    async def post_settings(self, request):
        try:
            body = await request.json()
            msg = self.apply_settings(body)
        except (ValueError, TypeError, KeyError) as exc:
            return _json_response({"error": str(exc)}, status=400)
        return _json_response({"ok": True, "message": msg, "settings": self.settings()})

    def apply_settings(self, body: dict) -> str:
        old = self.station.tracker
        roi = tuple(int(v) for v in body.get("roi_px", old.roi_px))
        threshold = int(body.get("threshold", old.threshold))
        flip = str(body.get("image_flip", old.image_flip))
        if flip not in FLIPS:
            raise ValueError(f"image_flip must be one of {FLIPS}")
        if len(roi) != 4:
            raise ValueError("roi_px must be [x, y, w, h]")
        view = self.station.snapshot.latest()
        if view is not None:
            h, w = view.raw_frame.shape[:2]
        elif getattr(self.station.meta, "frame_size", None):  # no frame yet: the source's
            w, h = (int(v) for v in self.station.meta.frame_size)
        else:
            raise ValueError("no camera frame yet: try again in a moment")
        if roi[0] < 0 or roi[1] < 0 or roi[2] < 8 or roi[3] < 8:
            raise ValueError(f"ROI {list(roi)}: x, y >= 0 and w, h >= 8 pixels")
        if roi[0] + roi[2] > w or roi[1] + roi[3] > h:
            raise ValueError(f"ROI {list(roi)} lies outside the {w}x{h} frame")
        if not 0 < threshold <= 256:
            raise ValueError(f"threshold must be in 1..256, got {threshold}")
        if (roi, threshold, flip) != (old.roi_px, old.threshold, old.image_flip):
            new = old.with_settings(roi_px=roi, image_flip=flip, threshold=threshold)
            self.station.tracker = new  # a reference swap: the vision loop takes it next frame
            self.config.camera.roi_px = roi
            self.config.camera.image_flip = flip
            self.config.tracker.threshold = threshold
        control: dict[str, float] = {}  # only the fields asked for: the others stay as set
        if "vibration_gain" in body:
            control["vibration_gain"] = float(body["vibration_gain"])
            if not control["vibration_gain"] >= 0:
                raise ValueError("vibration_gain must be >= 0")
        if "stiffness_n_per_mm" in body:
            k = float(body["stiffness_n_per_mm"])
            if not k > 0:
                raise ValueError("stiffness_n_per_mm must be > 0")
            control["stiffness_n_per_mm"] = k
        if "vibration_enabled" in body:
            control["vibration_enabled"] = 1.0 if body["vibration_enabled"] else 0.0
        if control:
            self.station.set_control(**control)
        return "applied"

    async def post_hold(self, request):
        """The operator hold: ``{"on": true|false}`` sets it, ``{}`` toggles it."""
        try:
            body = await request.json()
        except ValueError:
            body = {}
        if not isinstance(body, dict) or ("on" in body and not isinstance(body["on"], bool)):
            return web.json_response({"error": 'expected {"on": true|false} or {}'},
                                     status=400)
        if "on" in body:
            held = self.station.set_operator_hold(body["on"], "web")
        else:
            held = self.station.toggle_operator_hold("web")
        return web.json_response({"ok": True, "operator_hold": held})

    async def save(self, request):
        if self.config_path is None:
            return _json_response({"error": "the station was started without --config "
                                      "FILE: there is no configuration file to save to"},
                                     status=400)
        save_config(self.config, self.config_path)
        return _json_response({"ok": True, "message": f"saved {self.config_path}"})

    # -- experiment -----------------------------------------------------------------------

    async def exp_status(self, request):
        if self.session is None:
            return _json_response({"session": None, "results_dir": str(self.results_dir)})
        return _json_response({"session": self.session.status(),
                                  "results_dir": str(self.results_dir)})

    async def exp_start(self, request):
        try:
            body = await request.json()
            seed = body.get("seed")
            self.session = ExperimentSession.open(
                self.results_dir, str(body.get("participant", "")), self.stimuli,
                repeats=int(body.get("repeats", 3)),
                seed=None if seed in (None, "") else int(seed), present=self.stimulus)
        except (ExperimentError, ValueError, TypeError) as exc:
            return _json_response({"error": str(exc)}, status=400)
        return _json_response({"session": self.session.status()})

    async def exp_answer(self, request):
        if self.session is None:
            return _json_response({"error": "no session"}, status=400)
        try:
            body = await request.json()
            self.session.answer(str(body["answer"]), body.get("trial"))
        except (ExperimentError, ValueError, TypeError, KeyError) as exc:
            return _json_response({"error": str(exc)}, status=400)
        return _json_response({"session": self.session.status()})

    async def exp_plot(self, request):
        which = request.query.get("scope", "session")
        try:
            if which == "all":
                conf, _parts = report(self.results_dir)
                title = ""
            elif self.session is not None:
                conf, title = self.session.confusion(), ""
            else:
                return web.Response(status=404, text="no session")
        except ExperimentError as exc:
            return web.Response(status=404, text=str(exc))
        png = await asyncio.get_running_loop().run_in_executor(None, plot_png, conf, title)
        return web.Response(body=png, content_type="image/png",
                            headers={"Cache-Control": "no-store"})

    async def exp_report(self, request):
        try:
            conf, parts = report(self.results_dir)
        except ExperimentError as exc:
            return _json_response({"error": str(exc)}, status=404)
        return _json_response({"participants": parts, "confusion": conf.as_dict()})

    # -- the friction-gain staircase -----------------------------------------------------

    def _apply_b(self, b_v: float) -> None:
        """The staircase's b to the friction model the station renders (``friction_slot``:
        --texture when it is one), selected: the model the participant compares with the
        real sample."""
        if self.friction_slot is None:
            raise ExperimentError(self.friction_model)
        self.station.set_control(friction_b_v=b_v, texture_index=float(self.friction_slot),
                                 vibration_enabled=1.0)

    async def stairs_status(self, request):
        return _json_response({
            "staircase": self.staircase.status() if self.staircase is not None else None,
            # The friction model b goes to, or (unavailable) why the staircase cannot run.
            "friction_model": self.friction_model if self.friction_slot is not None else None,
            "unavailable": self.friction_model if self.friction_slot is None else None})

    async def stairs_start(self, request):
        if self.friction_slot is None:
            return _json_response({"error": self.friction_model}, status=400)
        try:
            body = await request.json()
            self.staircase = StaircaseSession.open(
                self.results_dir, str(body.get("participant", "")),
                start=float(body.get("start", 400.0)), step=float(body.get("step", 10.0)),
                present=self._apply_b)
        except (ExperimentError, ValueError, TypeError) as exc:
            return _json_response({"error": str(exc)}, status=400)
        return _json_response({"staircase": self.staircase.status()})

    async def stairs_answer(self, request):
        if self.staircase is None:
            return _json_response({"error": "no staircase"}, status=400)
        try:
            body = await request.json()
            self.staircase.answer(str(body["rougher"]), body.get("trial"))
        except (ExperimentError, ValueError, TypeError, KeyError) as exc:
            return _json_response({"error": str(exc)}, status=400)
        return _json_response({"staircase": self.staircase.status()})

    # -- the workspace calibration ---------------------------------------------------------

    async def cal_start(self, request):
        try:
            body = await request.json()
            self.calibration = PressCollector.for_workspace(
                self.station.tracker.workspace_mm, int(body.get("points", 9)),
                float(body.get("min_hold_s", 0.4)), float(body.get("clear_s", 1.0)))
        except (CalibrationError, ValueError, TypeError) as exc:
            return _json_response({"error": str(exc)}, status=400)
        self._calibration_fit = None
        return _json_response({"calibration": self.cal_state()})

    def cal_state(self) -> dict | None:
        cal = self.calibration
        if cal is None:
            return None
        out = cal.status()
        if cal.state == "done" and self._calibration_fit is None:
            view = self.station.snapshot.latest()
            h, w = view.raw_frame.shape[:2]
            try:
                hom, residual = cal.fit(self.station.tracker.image_flip, (w, h),
                                        self.config.camera.intrinsics)
                self._calibration_fit = {"matrix": list(hom.matrix), "rms_mm": hom.rms_mm,
                                         "residual_mm": residual.round(3).tolist(),
                                         "hom": hom}
            except CalibrationError as exc:
                self._calibration_fit = {"error": str(exc)}
        if self._calibration_fit is not None:
            out["fit"] = {k: v for k, v in self._calibration_fit.items() if k != "hom"}
        return out

    async def cal_status(self, request):
        return _json_response({"calibration": self.cal_state()})

    async def cal_cancel(self, request):
        self.calibration, self._calibration_fit = None, None
        return _json_response({"calibration": None})

    async def cal_save(self, request):
        """Apply the fitted homography live and write it to the configuration file."""
        fit = self._calibration_fit
        if fit is None or "hom" not in fit:
            return _json_response({"error": "no fitted calibration to save"}, status=400)
        hom = fit["hom"]
        tr = self.station.tracker
        self.station.tracker = tr.with_settings(calibration=CalibratedMapping(
            hom, self.config.camera.intrinsics, tr.image_flip))
        self.config.camera = dataclasses.replace(self.config.camera,
                                                 workspace_homography=hom)
        if self.config_path is None:
            return _json_response({"ok": True, "message": "applied; not saved: the "
                                      "station was started without --config FILE"})
        save_config(self.config, self.config_path)
        return _json_response({"ok": True, "message": f"applied and saved "
                                  f"{self.config_path} [camera.workspace_homography]"})

    def app(self) -> web.Application:
        app = web.Application(middlewares=[self.auth], client_max_size=64 * 1024)
        app.router.add_get("/", self.index)
        app.router.add_get("/experiment", self.experiment_page)
        app.router.add_get("/calibrate", self.calibrate_page)
        app.router.add_get("/indentation-guide", indentation_guide)
        app.router.add_get("/api/state", self.state)
        app.router.add_get("/api/frame.jpg", self.frame_jpg)
        app.router.add_post("/api/settings", self.post_settings)
        app.router.add_post("/api/hold", self.post_hold)
        app.router.add_post("/api/save", self.save)
        app.router.add_get("/api/experiment", self.exp_status)
        app.router.add_post("/api/experiment/start", self.exp_start)
        app.router.add_post("/api/experiment/answer", self.exp_answer)
        app.router.add_get("/api/experiment/plot.png", self.exp_plot)
        app.router.add_get("/api/experiment/report", self.exp_report)
        app.router.add_get("/api/staircase", self.stairs_status)
        app.router.add_post("/api/staircase/start", self.stairs_start)
        app.router.add_post("/api/staircase/answer", self.stairs_answer)
        app.router.add_get("/api/calibration", self.cal_status)
        app.router.add_post("/api/calibration/start", self.cal_start)
        app.router.add_post("/api/calibration/cancel", self.cal_cancel)
        app.router.add_post("/api/calibration/save", self.cal_save)
        app.router.add_static("/static/", STATIC)
        return app


class WebServer:
    """The running server: ``url``, ``stop()``."""

    def __init__(self, view: WebView, host: str, port: int):
        self.view = view
        self.host = host
        self._port = port
        self.port: int | None = None
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._runner: web.AppRunner | None = None
        self._thread = threading.Thread(target=self._main, name="fydpad-web", daemon=True)

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        tok = f"/?token={self.view.token}" if self.view.token else "/"
        return f"http://{host}:{self.port}{tok}"

    def _main(self) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._start())
        except BaseException as exc:  # reported to start()
            self._error = exc
            self._ready.set()
            return
        self._ready.set()
        try:
            self._loop.run_forever()
        finally:
            self._loop.run_until_complete(self._runner.cleanup())
            self._loop.close()

    async def _start(self) -> None:
        self._runner = web.AppRunner(self.view.app(), access_log=None)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self._port)
        await site.start()
        self.port = self._runner.addresses[0][1]
        self._sampler = asyncio.ensure_future(self.view.sampler())

    def start(self) -> WebServer:
        self._thread.start()
        self._ready.wait(10)
        if self._error is not None:
            raise OSError(f"web view on {self.host}:{self._port}: {self._error}")
        return self

    def stop(self) -> None:
        if self._thread.is_alive():
            def _halt():
                self._sampler.cancel()
                self._loop.stop()
            self._loop.call_soon_threadsafe(_halt)
            self._thread.join(timeout=5)


def start_web(station, config, config_path=None, host: str = "127.0.0.1", port: int = 8080,
              token: str | None = None, results_dir: str | Path = "experiment-results",
              texture_hook=None, stimuli: tuple[Stimulus, ...] | list[Stimulus] = PAPER_STIMULI
              ) -> WebServer:
    """Serve the station's web view; off loopback a token is required (made if absent).
    ``stimuli``: the experiment's (their textures rendered if ``RenderSpec.textures``
    has them)."""
    if token is None and not is_loopback(host):
        token = secrets.token_urlsafe(16)
    view = WebView(station, config, config_path, results_dir, token, texture_hook, stimuli)
    return WebServer(view, host, port).start()


def parse_web_address(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` -> (host, port); the host defaults to loopback."""
    host, _, port = text.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    try:
        p = int(port)
    except ValueError:
        raise ValueError(f"--web: expected [HOST:]PORT, got {text!r}") from None
    if not 0 <= p <= 65535:
        raise ValueError(f"--web: port {p} out of range")
    return host, p
