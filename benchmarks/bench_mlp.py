"""Neural-network texture benchmarks, run on demand: ``python benchmarks/bench_mlp.py``.

Each figure is printed beside a baseline measured in the same run:
- ``MlpTexture.tick`` (the 1 kHz path: preallocated arrays, weights with the scaling and
  logsig folded in, four NumPy calls, no array temporaries) against a naive NumPy
  forward pass that builds its input vector and every intermediate per tick;
- ``MlpTexture.render`` per sample (offline, vectorised) against the tick loop;
- one training epoch of the thesis' per-sample steepest descent against the vectorised
  full-batch epoch on the same data.
"""

from __future__ import annotations

import tracemalloc
import warnings

import numpy as np
from timing import best

from fydpad.texture.families.mlp.model import thesis_model
from fydpad.texture.families.mlp.render import MlpTexture
from fydpad.texture.families.mlp.train import TrainConfig, _batch_epoch, _online_epoch, init_net
from fydpad.texture.family import constant_stroke


def naive_tick(model, state, x_mm, y_mm, speed, force):
    """Same equations with ordinary NumPy: new arrays for input, hidden layer, output."""
    th = state["th"]
    if x_mm != state["x"] or y_mm != state["y"]:
        th = np.arctan2(y_mm - state["y"], x_mm - state["x"])
    state.update(x=x_mm, y=y_mm, th=th)
    df = force - state["m"]
    state["m"] += state["alpha"] * df
    u = (np.array([speed * np.cos(th), speed * np.sin(th), df]) - model.scaling.in_offset) \
        * model.scaling.in_scale
    h = 1.0 / (1.0 + np.exp(-(model.net.w_in @ u + model.net.b_in)))
    r = model.scaling.out_offset + model.scaling.out_scale * (h @ model.net.w_out + model.net.b_out)
    y = r - state["r"] + state["R"] * state["y_hp"]
    state.update(r=r, y_hp=y)
    return (float(y),)


def main() -> None:
    warnings.simplefilter("ignore")
    model = thesis_model()
    n = 20_000
    fb = constant_stroke(25.0, n / 1000.0, 1000.0)
    args = [(float(fb.t_s[k]), True, float(fb.x_mm[k]), 0.0, 25.0,
             1.0 + 0.05 * np.sin(k / 7)) for k in range(n)]
    fam = MlpTexture(model)

    def run_tick():
        tick = fam.tick
        for a in args:
            tick(*a)

    state = {"x": np.nan, "y": np.nan, "th": 0.0, "m": 1.0, "r": 0.0, "y_hp": 0.0,
             "alpha": 1 - np.exp(-1 / 50), "R": np.exp(-2 * np.pi * 5 / 1000)}

    def run_naive():
        for a in args:
            naive_tick(model, state, a[2], a[3], a[4], a[5])

    print("mlp texture benchmarks (3-10-1 network, 1 kHz)")
    t_tick = best(run_tick, 5) / n
    t_naive = best(run_naive, 5) / n
    print(f"  tick: {t_tick * 1e6:.2f} us per sample (budget 1000 us at 1 kHz); naive NumPy "
          f"baseline {t_naive * 1e6:.2f} us ({t_naive / t_tick:.1f}x)")
    tracemalloc.start()
    run_tick()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"  tick: {peak} bytes peak traced over {n} ticks (no per-tick arrays)")
    fb2 = constant_stroke(25.0, n / 1000.0, 1000.0)
    t_render = best(lambda: MlpTexture(model).render(fb2), 5) / n
    print(f"  render: {t_render * 1e9:.0f} ns per sample ({t_tick / t_render:.0f}x the tick loop)")

    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, (16_000, 3))
    y = np.tanh(u @ np.array([1.0, -0.5, 0.3]))
    net_o, net_b = init_net(3, TrainConfig()), init_net(3, TrainConfig())
    t_on = best(lambda: _online_epoch(net_o, u, y, 0.1), 3)
    t_ba = best(lambda: _batch_epoch(net_b, u, y, 0.9), 7)
    print(f"  training epoch, 16k samples: per-sample (thesis) {t_on * 1e3:.0f} ms; "
          f"batch {t_ba * 1e3:.2f} ms ({t_on / t_ba:.0f}x faster); 2000 epochs per-sample "
          f"{2000 * t_on:.0f} s")


if __name__ == "__main__":
    main()
