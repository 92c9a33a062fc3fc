"""Throughput of Experiment 6: the time of each training stage (completion map, forward models, the
confirm stage's cut) and of the tests (the trials of all participants, batched, the pybullet views
included; then the stage measures of ``evaluate``), in all and per participant.

    python benchmarks/bench_exp6.py [participants] [quick|full] [threads] [fm_images]

``threads``: the run's thread budget (as ``evaluate.py threads=``; default 1); ``fm_images``
overrides ``experiment.fm.images`` (a shorter run for profiling; the default keeps the model's).
"""
import sys
import time
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir

from neuroimagery.config import register_configs, validate
from neuroimagery.experiments.exp6 import protocol as exp6, stages as exp6_stages
from neuroimagery.experiments.exp6.data import make_scene
from neuroimagery.nn.functional import intra_op_threads


def _clock(what: str, times: dict, fn, *args):
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn(*args)
    times[what] = (time.perf_counter() - t0, time.process_time() - c0)
    return out


def main(participants: int = 10, preset: str = "full", threads: int = 1, fm_images: int | None = None) -> None:
    register_configs()
    overrides = ["experiment=exp6", f"participants={participants}", "logger=none"]
    if fm_images is not None:
        overrides.append(f"experiment.fm.images={fm_images}")
    with initialize_config_dir(config_dir=str(Path(__file__).resolve().parents[1] / "conf"), version_base="1.3"):
        cfg = validate(compose("config", overrides=overrides))
    cfg.preset = preset
    ids = list(range(participants))
    times: dict[str, tuple[float, float]] = {}
    scene = make_scene(cfg.experiment)
    try:
        with intra_op_threads(threads):
            model = exp6._model(cfg, ids)
            model.train()
            with intra_op_threads(cfg.experiment.train_threads, cap=True):  # as exp6.train_model
                _clock("train: completion map", times, exp6.train_completion, model, cfg, ids, scene)
                _clock("train: forward models", times, exp6.train_forward_models, model, cfg, ids)
                model.eval()
                _clock("train: confirm cut", times, exp6.fit_confirm, model, cfg, ids, scene)
            df, _, _ = _clock("test: trials", times, exp6.run_tests, cfg, model, scene)
            _clock("test: stage measures", times, exp6_stages.measure, model, cfg, scene)
    finally:
        scene.close()
    print(f"exp6 ({preset}, {participants} participants, threads={threads}, fm.images="
          f"{cfg.experiment.fm.images if preset == 'full' else cfg.experiment.quick.fm_images}, "
          f"{len(df)} trials):")
    for group in ("train", "test"):
        keys = [k for k in times if k.startswith(group)]
        wall, cpu = sum(times[k][0] for k in keys), sum(times[k][1] for k in keys)
        for k in keys:
            print(f"  {k:24s} {times[k][0]:7.1f} s ({times[k][0] / participants:6.1f} s per participant, "
                  f"CPU {times[k][1]:7.1f} s)")
        print(f"  {group + ' in all':24s} {wall:7.1f} s ({wall / participants:6.1f} s per participant, CPU {cpu:7.1f} s)")
    print(f"  trials per second: {len(df) / times['test: trials'][0]:.1f}")


if __name__ == "__main__":
    a = sys.argv[1:]
    main(int(a[0]) if a else 10, a[1] if len(a) > 1 else "full", int(a[2]) if len(a) > 2 else 1,
         int(a[3]) if len(a) > 3 else None)
