"""Output channels when things go wrong: a file channel's writer thread never closes its
file under a write in progress, drains (or drops) what is queued as asked, and a channel
whose disk fails mid-run is reported in one line naming it, while the other channels,
the motors' safe stop, the commands log and the render process's final statistics all
still happen.

The full disk is Linux's ``/dev/full`` (every write fails with ENOSPC): a real device,
not a fake. The slow disk is a fake channel whose ``write`` blocks on an event: the
boundary (a disk stalling mid-write) cannot be produced on demand here.
"""

from __future__ import annotations

import threading
import wave
from pathlib import Path

import numpy as np
import pytest

from fydpad.channels import ChannelError
from fydpad.channels.files import WavChannel
from fydpad.station.outputs import ChannelOutputs, FileWriter
from tests.conftest import write_blob_recording

FULL = Path("/dev/full")
needs_dev_full = pytest.mark.skipif(not FULL.exists(), reason="no /dev/full on this system")


class GatedChannel:
    """A channel whose writes wait for ``gate``: a disk that stalls mid-write."""

    name, rate_hz = "vibration", 1000.0

    def __init__(self) -> None:
        self.gate = threading.Event()
        self.entered = threading.Event()  # a write has started
        self.samples: list[float] = []
        self.writing = False
        self.closed = False
        self.closed_during_write = False

    def write(self, block: np.ndarray) -> None:
        self.writing = True
        self.entered.set()
        self.gate.wait(30)
        self.samples.extend(block.tolist())
        self.writing = False

    def close(self) -> None:
        self.closed_during_write |= self.writing
        self.closed = True


@pytest.mark.parametrize("drain", [True, False])
def test_file_writer_never_closes_under_a_write_and_drains_as_asked(drain: bool):
    ch = GatedChannel()
    fw = FileWriter(ch)
    fw.write(np.full(10, 0.0))
    assert ch.entered.wait(30)  # block 0 is being written
    for k in range(1, 5):  # 1-4 wait in the ring
        fw.write(np.full(10, float(k)))
    with pytest.raises(ChannelError, match=r"still writing after 0\.2 s"):
        fw.close(drain=drain, timeout_s=0.2)
    assert not ch.closed  # not under the stalled write
    ch.gate.set()
    fw._thread.join(30)
    assert not fw._thread.is_alive()
    assert ch.closed and not ch.closed_during_write  # closed once the writes were done
    sent = np.repeat(np.arange(5.0), 10).tolist()
    if drain:
        assert ch.samples == sent
    else:  # the write in progress finishes; what is still buffered is dropped, counted
        assert ch.samples == sent[:10] and fw.stats["discarded_samples"] == 40
    fw.close(drain=drain)  # closing again: nothing left to report


def test_file_writer_drains_every_queued_block_into_the_wav(tmp_path: Path):
    fw = FileWriter(WavChannel(tmp_path / "v.wav", 1000.0))
    for k in range(200):
        fw.write(np.full(10, (k % 7) / 10))
    fw.close(drain=True)
    with wave.open(str(tmp_path / "v.wav")) as w:
        pcm = np.frombuffer(w.readframes(w.getnframes()), "<i2")
    assert pcm.size == 2000
    np.testing.assert_array_equal(pcm[::10], np.round(np.arange(200) % 7 / 10 * 32767))


@needs_dev_full
def test_a_channel_on_a_full_disk_is_named_once_and_the_others_complete(
        friction_model: Path, tmp_path: Path):
    from fydpad.station.chains import _TickModel

    model = _TickModel(str(friction_model), 1000.0)
    out = ChannelOutputs([f"wav:{FULL}", f"csv:{tmp_path / 'v.csv'}"], [model], 1000.0, 10)
    raised: list[str] = []
    ticks = 0
    for k in range(600):  # as the render loop: a raise from a tick stops it
        vals = model.family.tick(k / 1000, True, 0.05 * k, 0.0, 50.0, 0.5)
        ticks += 1
        try:
            out.tick(k / 1000, True, 0.05 * k, 0.0, 50.0, 0.5, 1.0, 0, vals, vals[0])
        except ChannelError as exc:
            raised.append(str(exc))
            break
    closing = out.close()  # never raises
    reports = raised + closing
    assert reports, "the full disk went unreported"
    for line in reports:
        assert f"wav:{FULL}" in line and "No space left on device" in line
        assert "\n" not in line
    # The write failure is reported once (by the tick or by the close), not per block.
    assert sum(line.count("write failed") for line in reports) == 1
    assert out.stats()[f"wav:{FULL}"]["failed"].startswith(f"channel wav:{FULL}: ")
    # The other channel got every tick and its file was closed.
    csv_route = out.routes[1]
    assert csv_route.failed is None and csv_route.out.channel._f.closed
    rows = np.genfromtxt(tmp_path / "v.csv", delimiter=",", names=True)
    assert rows.size == ticks == csv_route.n_samples
    assert out.close() == []  # a second close reports nothing new


@needs_dev_full
def test_station_reports_a_full_disk_channel_and_still_gets_the_render_stats(
        friction_model: Path, tmp_path: Path):
    """The real render process (simulated motors, a friction model): its WAV channel on a
    full disk stops the station with a fault naming the file; the motors' safe stop, the
    other channel, the commands log and the final statistics all still happen."""
    from fydpad.config import StationConfig
    from fydpad.station.render import RenderSpec
    from fydpad.station.station import Station, StationFault, StationOptions
    from vision.contact import ContactTracker
    from vision.recording import PadRecording
    from vision.sources import VideoSource

    rec = tmp_path / "rec"
    write_blob_recording(rec, [(20 * np.cos(k / 8), 15 * np.sin(k / 8)) for k in range(60)])
    r = PadRecording(rec)
    m = r.meta
    spec = RenderSpec(motors="sim", texture=str(friction_model), config=StationConfig(),
                      channels=(f"wav:{FULL}", f"csv:{tmp_path / 'v.csv'}"), realtime=False,
                      commands_csv=str(tmp_path / "commands.csv"))
    station = Station(VideoSource(r), ContactTracker(roi_px=m.roi_px,
                                                      workspace_mm=m.workspace_mm,
                                                      image_flip=m.image_flip),
                      m, StationOptions(render=spec))
    with pytest.raises(StationFault) as err:
        station.run()
    message = str(err.value)
    assert f"wav:{FULL}" in message and "No space left on device" in message
    assert "\n" not in message
    # The final statistics came (the station does not wait them out): safe stop ran.
    render = station.stats["render"]
    assert render["ticks"] > 0
    channels = render["chain"]["channels"]
    assert "failed" in channels[f"wav:{FULL}"]
    csv_stats = channels[f"csv:{tmp_path / 'v.csv'}"]
    assert "failed" not in csv_stats and csv_stats["written"] == csv_stats["samples"] > 0
    # The commands log was closed whole: every row complete, up to the failing tick.
    cmds = (tmp_path / "commands.csv").read_text()
    lines = cmds.splitlines()
    assert cmds.endswith("\n") and len(lines) > 1
    assert {line.count(",") for line in lines} == {lines[0].count(",")}
