"""Which master owns the arm, and which of its samples the slave admits (docs/protocol.md).

Every decoded sample is judged in this order and refused with the first reason that
applies, counted by name: ``nonfinite``, ``not_owner``, ``duplicate``, ``out_of_order``,
``future``, ``stale``. Order and clock are kept per master (ZeroMQ routing id), and the
master's clock is estimated from its own samples so that no single sample moves it much:

    d_k = t_recv_k (slave clock) - t_send_k (master clock)
    offset = the 10th percentile (nearest rank, rounded down) of d over the master's last
             ``safety.clock_window`` samples: the clock offset plus a short latency. A
             sample that claims a later clock (a small d) is one rank among 64; the lowest
             tenth of the window never sets the estimate once the window is full.
    master clock now ~ t_recv - offset

Pure: the caller passes the slave-clock time in.
"""

from __future__ import annotations

import logging
import math
from collections import Counter, OrderedDict, deque
from dataclasses import dataclass, field

from teleop.config import SafetyConfig
from teleop.protocol import Sample

log = logging.getLogger(__name__)

REASONS = ("nonfinite", "not_owner", "duplicate", "out_of_order", "future", "stale")
RECENT_SEQS = 1024  # accepted seqs remembered per master: a replay among them is a duplicate
MAX_MASTERS = 64  # masters tracked at once; the least recently heard non-owner is forgotten
CLOCK_PERCENTILE = 10


def peer_name(ident: bytes) -> str:
    """A routing id as a log-friendly hex string."""
    return ident.hex() if ident else "(none)"


@dataclass
class MasterTrack:
    """What the slave knows of one master: its clock and the order of its samples."""

    ident: bytes
    window: int
    d_s: deque[float] = field(init=False)
    last_seq: int | None = None  # None: nothing accepted from this master yet
    last_t_capture_s: float = -math.inf
    recent: deque[int] = field(default_factory=lambda: deque(maxlen=RECENT_SEQS))
    recent_set: set[int] = field(default_factory=set)
    logged: set[str] = field(default_factory=set)  # drop reasons already logged for it
    _offset_s: float | None = None  # cached estimate; None after a new delay

    def __post_init__(self) -> None:
        self.d_s = deque(maxlen=self.window)

    def add_delay(self, d_s: float) -> None:
        self.d_s.append(d_s)
        self._offset_s = None

    def offset_s(self) -> float:
        """Slave clock minus this master's clock (+ a short latency): module docstring."""
        if self._offset_s is None:
            d = sorted(self.d_s)
            self._offset_s = d[len(d) * CLOCK_PERCENTILE // 100]
        return self._offset_s

    def remember(self, s: Sample) -> None:
        if len(self.recent) == self.recent.maxlen:
            self.recent_set.discard(self.recent[0])
        self.recent.append(s.seq)
        self.recent_set.add(s.seq)
        self.last_seq = s.seq
        self.last_t_capture_s = s.t_capture_s


class Admission:
    """One owner at a time; per-master order and clock; every refusal counted by reason."""

    def __init__(self, cfg: SafetyConfig) -> None:
        if cfg.clock_window < 1:
            raise ValueError(f"safety.clock_window must be >= 1, got {cfg.clock_window}")
        self.cfg = cfg
        self.owner: bytes | None = None
        self.tracks: OrderedDict[bytes, MasterTrack] = OrderedDict()
        self.dropped: Counter[str] = Counter()
        self.takeovers = 0  # times a master took the free arm
        self.acquired = False  # the last admitted sample made its master the owner

    @property
    def dropped_total(self) -> int:
        return sum(self.dropped.values())

    def owner_offset_s(self) -> float | None:
        t = self.tracks.get(self.owner) if self.owner is not None else None
        return t.offset_s() if t is not None and t.d_s else None

    def _track(self, ident: bytes) -> MasterTrack:
        t = self.tracks.get(ident)
        if t is None:
            if len(self.tracks) >= MAX_MASTERS:
                for old in self.tracks:
                    if old != self.owner:
                        del self.tracks[old]
                        break
            t = self.tracks[ident] = MasterTrack(ident, self.cfg.clock_window)
        else:
            self.tracks.move_to_end(ident)
        return t

    def _drop(self, reason: str, track: MasterTrack | None, ident: bytes, s: Sample,
              detail: str) -> str:
        self.dropped[reason] += 1
        if track is None or reason not in track.logged:
            if track is not None:
                track.logged.add(reason)
            log.warning("master %s: dropped a sample (seq %d) as %s: %s (logged once per "
                        "master and reason; all are counted)", peer_name(ident), s.seq, reason,
                        detail)
        return reason

    def judge(self, ident: bytes, s: Sample, now_s: float) -> str | None:
        """None if ``s`` is admitted (``ident`` then owns the arm), else the drop reason."""
        self.acquired = False
        need = (s.t_capture_s, s.t_send_s, s.z_mm) + ((s.x_mm, s.y_mm) if s.contact else ())
        if not all(math.isfinite(v) for v in need):
            return self._drop("nonfinite", self.tracks.get(ident), ident, s,
                              "times, z, and x, y in contact must be finite")
        track = self._track(ident)
        track.add_delay(now_s - s.t_send_s)
        if self.owner is not None and ident != self.owner:
            return self._drop("not_owner", track, ident, s,
                              f"master {peer_name(self.owner)} owns the arm until it is "
                              f"silent for {self.cfg.watchdog_s * 1e3:.0f} ms")
        if track.last_seq is not None:
            if s.seq in track.recent_set:
                return self._drop("duplicate", track, ident, s, "seq already accepted")
            if s.seq < track.last_seq or s.t_capture_s <= track.last_t_capture_s:
                return self._drop("out_of_order", track, ident, s,
                                  f"last accepted seq {track.last_seq}, capture time "
                                  f"{track.last_t_capture_s!r} s")
            if s.seq - track.last_seq > self.cfg.max_seq_step:
                return self._drop("future", track, ident, s,
                                  f"seq more than {self.cfg.max_seq_step} after the last "
                                  f"accepted {track.last_seq}")
        master_now_s = now_s - track.offset_s()
        if s.t_capture_s - master_now_s > self.cfg.future_tolerance_s:
            return self._drop("future", track, ident, s,
                              f"capture time {s.t_capture_s!r} s is "
                              f"{s.t_capture_s - master_now_s:.3g} s ahead of the master's "
                              "clock as the slave estimates it")
        if master_now_s - s.t_capture_s > self.cfg.max_age_s:
            return self._drop("stale", track, ident, s,
                              f"captured {master_now_s - s.t_capture_s:.3g} s ago")
        track.remember(s)
        if self.owner is None:
            self.owner = ident
            self.takeovers += 1
            self.acquired = True
            log.info("master %s owns the arm", peer_name(ident))
        return None

    def release(self) -> bytes | None:
        """The owner fell silent past the watchdog and the arm holds: free the arm and forget
        every master's order and clock (the owner may come back restarted, with seq and
        clock anew; a waiting master is judged on what it sends from now on)."""
        owner, self.owner = self.owner, None
        for t in self.tracks.values():
            t.d_s.clear()
            t._offset_s = None
            t.last_seq = None
            t.last_t_capture_s = -math.inf
            t.recent.clear()
            t.recent_set.clear()
        if owner is not None:
            self.tracks.pop(owner, None)
            log.warning("master %s silent for %.0f ms: holding; the next master to stream "
                        "valid samples owns the arm", peer_name(owner), self.cfg.watchdog_s * 1e3)
        return owner
