"""Training the refine colour net: inputs hold the diffusion fill, losses fall, runs
resume (with or without the adversarial term), the held-out score is logged."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from trainkit import ALEXNET, CROP, REGION_SIZE, one_thread_fake_cache, write_folder

torch = pytest.importorskip("torch")

from photo3d.cli import main  # noqa: E402
from photo3d.errors import ConfigError  # noqa: E402
from photo3d.eval.heldout_data import first_pass_shapes  # noqa: E402
from photo3d.inpaint.learned import is_refine  # noqa: E402
from photo3d.nets.weights import load_net  # noqa: E402
from photo3d.train import (  # noqa: E402
    TrainConfig,
    Trainer,
    checkpoints,
    find_training_files,
    make_batch,
    prepare_data,
    to_tensors,
    train,
)
from photo3d.train.heldout import HeldoutSet  # noqa: E402

REFINE = dict(arch="refine", channels=4, levels=2, blocks=1)


@pytest.fixture(autouse=True)
def one_thread(tmp_path_factory, monkeypatch):
    yield from one_thread_fake_cache(tmp_path_factory, monkeypatch, lpips=True)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return write_folder(tmp_path_factory.mktemp("train"))


@pytest.fixture(scope="module")
def data(folder):
    files = find_training_files(folder / "images", depth=folder / "depth")
    return prepare_data(files, crop=CROP, region_size=REGION_SIZE)


def config(**changes) -> TrainConfig:
    return TrainConfig("color", **{**REFINE, "size": CROP, "batch": 4, **changes})


def small_heldout(folder: Path) -> HeldoutSet:
    """Three fixture photos and the region shapes of a depth map with two boxes."""
    d = np.ones((96, 128), np.float32)
    d[20:60, 24:64] = 3.0
    d[50:80, 80:116] = 2.0
    from photo3d.config import Config

    bank = tuple(first_pass_shapes(d, source="boxes", config=Config(size=None),
                                   min_synthesis=32, min_context=32))
    from photo3d.eval.heldout_data import load_photo

    files = sorted((folder / "images").iterdir())[:3]
    return HeldoutSet(tuple(load_photo(p, 128) for p in files), tuple(p.name for p in files),
                      bank)


def test_refine_samples_hold_the_diffusion_fill_under_the_hole(data):
    plain = make_batch(data, "color", size=CROP, batch=2, seed=0, step=3)
    filled = make_batch(data, "color", size=CROP, batch=2, seed=0, step=3, refine=True)
    for p, f in zip(plain, filled, strict=True):
        np.testing.assert_array_equal(p.inputs[3:], f.inputs[3:])  # same crop and masks
        np.testing.assert_array_equal(f.inputs[:3][:, p.context], p.inputs[:3][:, p.context])
        assert not p.inputs[:3][:, p.hole].any()
        assert f.inputs[:3][:, p.hole].std() > 0  # the fill, not zeros
        assert not f.inputs[:3][:, ~(p.hole | p.context)].any()


def test_losses_fall_on_a_fixed_batch(data):
    trainer = Trainer(config(lr=2e-3), device="cpu")
    assert is_refine(trainer.net)
    batch = to_tensors(make_batch(data, "color", size=CROP, batch=4, seed=0, step=1,
                                  refine=True), trainer.device)
    history = [trainer.step(batch)[0] for _ in range(10)]
    totals = [h["total"] for h in history]
    assert all(np.isfinite(v) for h in history for v in h.values())
    assert {"hole", "perceptual", "hole_style", "total"} <= set(history[0])
    assert "context" not in history[0]  # the net returns the context as given
    assert totals[-1] < totals[0] and np.mean(totals[-3:]) < np.mean(totals[:3])


def test_checkpoint_round_trip_and_adversarial_resume(data, tmp_path):
    a = Trainer(config(seed=1), device="cpu")
    batch = to_tensors(make_batch(data, "color", size=CROP, batch=4, seed=0, step=1,
                                  refine=True), a.device)
    a.step(batch)
    a.save(tmp_path / "ckpt", step=1)
    b = Trainer(config(seed=2), device="cpu")
    assert b.load(tmp_path / "ckpt") == 1
    la, _ = a.step(batch)
    lb, _ = b.step(batch)
    assert la == pytest.approx(lb, rel=1e-5)
    # resumed with the adversarial term: the discriminator starts fresh, then round-trips
    c = Trainer(config(seed=3, adversarial=0.1), device="cpu")
    assert c.load(tmp_path / "ckpt") == 1
    terms, _ = c.step(batch)
    assert {"adv", "d_total", "d_real", "d_fake"} <= set(terms)
    c.save(tmp_path / "ckpt2", step=2)
    assert (tmp_path / "ckpt2" / "discriminator.safetensors").is_file()
    d = Trainer(config(seed=4, adversarial=0.1), device="cpu")
    assert d.load(tmp_path / "ckpt2") == 2
    for p, q in zip(c.discriminator.parameters(), d.discriminator.parameters(), strict=True):
        torch.testing.assert_close(p, q)


def test_a_run_resumes_and_logs_the_heldout_score(data, folder, tmp_path):
    if not ALEXNET.is_file():
        pytest.skip("LPIPS weights not cached")
    heldout = small_heldout(folder)
    run = tmp_path / "run"
    first = train(data, run, config(steps=2, checkpoint_every=1, heldout_every=1),
                  device="cpu", heldout=heldout)
    assert (first.start_step, first.step) == (0, 2)
    second = train(data, run, config(steps=3, checkpoint_every=1, heldout_every=2),
                   device="cpu", heldout=heldout)
    assert (second.start_step, second.step) == (2, 3)
    with open(run / "heldout.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(int(r["step"]), r["method"]) for r in rows] == [
        (0, "diffusion"), (0, "net"), (1, "net"), (2, "net"), (3, "net")]
    # a fresh net is the diffusion fill: same scores
    assert float(rows[1]["psnr"]) == pytest.approx(float(rows[0]["psnr"]), abs=1e-4)
    assert all(0 <= float(r["lpips"]) < 1 and np.isfinite(float(r["psnr"])) for r in rows)
    net, _ = load_net("color", run)
    assert is_refine(net)
    with pytest.raises(ConfigError, match="holds a color run with channels 4, not 8"):
        train(data, run, config(steps=4, channels=8), device="cpu")


def test_cli_two_steps_with_heldout_then_resume(folder, tmp_path, monkeypatch, capsys):
    if not ALEXNET.is_file():
        pytest.skip("LPIPS weights not cached")
    import photo3d.eval.heldout_data as hd

    monkeypatch.setattr(hd, "region_bank", lambda size=640: small_heldout(folder).bank)
    run = tmp_path / "run"
    args = ["train", "color", "--arch", "refine", "--channels", "4", "--levels", "2",
            "--blocks", "1", "--no-edges", "--images", str(folder / "images"),
            "--size", str(CROP), "--region-size", str(REGION_SIZE), "--shape-scenes", "2",
            "--batch", "2", "--device", "cpu", "--threads", "1", "--out", str(run),
            "--heldout", str(folder / "images"), "--heldout-photos", "2"]
    assert main([*args, "--steps", "2"]) == 0
    out = capsys.readouterr().out
    assert "arch refine" in out and "trained 2 steps" in out and "heldout.csv" in out
    assert main([*args, "--steps", "3", "-q"]) == 0
    with open(run / "losses.csv", newline="") as f:
        assert [int(r["step"]) for r in csv.DictReader(f)] == [1, 2, 3]
    with open(run / "heldout.csv", newline="") as f:
        assert [r["step"] for r in csv.DictReader(f)] == ["0", "0", "2", "3"]
    assert [s for s, _ in checkpoints(run)] == [2, 3]
    net, _ = load_net("color", run)
    assert is_refine(net) and net.config["edges"] is False


def test_refine_options_are_checked():
    with pytest.raises(ConfigError, match="is a colour net"):
        TrainConfig("depth", arch="refine")
    with pytest.raises(ConfigError, match="unknown architecture"):
        TrainConfig("color", arch="lama")
    with pytest.raises(ConfigError, match="refine net only"):
        TrainConfig("color", adversarial=0.1)
    assert (TrainConfig("color", arch="refine", size=128).levels,
            TrainConfig("color", size=128).levels, TrainConfig("edge").blocks) == (4, 7, 8)


def test_refine_loss_sees_the_hole_only():
    from photo3d.train import losses

    torch.manual_seed(0)
    target = torch.rand(2, 3, 32, 32)
    hole = torch.zeros(2, 1, 32, 32)
    hole[..., 8:24, 10:20] = 1
    identity = lambda t: [t, torch.nn.functional.avg_pool2d(t, 2)]  # noqa: E731
    weights = dict(losses.REFINE_WEIGHTS, style=1.0, hole_style=1.0)
    old = dict(losses.REFINE_WEIGHTS)
    losses.REFINE_WEIGHTS.update(weights)
    try:
        exact = losses.refine_loss(target, target, hole, identity)
        assert all(float(v) == 0 for k, v in exact.items() if k not in ("tv", "total"))
        # whatever the output holds outside the hole is never scored
        outside = target + (1 - hole) * torch.rand(2, 3, 32, 32)
        assert losses.refine_loss(outside, target, hole, identity)["total"] == exact["total"]
        blurred = target.clone()
        blurred[..., 8:24, 10:20] = target[..., 8:24, 10:20].mean()
        terms = losses.refine_loss(blurred, target, hole, identity)
        assert terms["hole"] > 0 and terms["hole_style"] > 0 and terms["perceptual"] > 0
        # texture statistics inside the hole: a flat hole in a textured crop differs
        flat = torch.full((1, 2, 4, 4), 0.5)
        m = torch.zeros(1, 1, 4, 4)
        m[..., :2] = 1
        assert torch.allclose(losses.masked_gram(flat, m), losses.gram(flat[..., :2]))
    finally:
        losses.REFINE_WEIGHTS.clear()
        losses.REFINE_WEIGHTS.update(old)


def test_swap_probability(data):
    never = make_batch(data, "color", size=CROP, batch=6, seed=0, step=2, swap=0.0)
    always = make_batch(data, "color", size=CROP, batch=6, seed=0, step=2, swap=1.0)
    assert not any(s.swapped for s in never) and all(s.swapped for s in always)
    paper = make_batch(data, "color", size=CROP, batch=6, seed=0, step=2)
    again = make_batch(data, "color", size=CROP, batch=6, seed=0, step=2, swap=0.5)
    assert [s.swapped for s in paper] == [s.swapped for s in again]
    with pytest.raises(ConfigError, match="probability"):
        TrainConfig("color", swap=1.5)


def test_a_resumed_log_gains_the_new_terms_columns(tmp_path):
    from photo3d.train.run import _LossLog

    path = tmp_path / "losses.csv"
    log = _LossLog(path, 0)
    log.write(1, 0.5, {"hole": 1.0, "total": 2.0})
    log.write(2, 0.5, {"hole": 1.0, "total": 2.0})
    resumed = _LossLog(path, 2)  # resumed with an adversarial term
    resumed.write(3, 0.5, {"hole": 1.0, "total": 2.0, "adv": 0.3})
    rows = path.read_text().splitlines()
    assert rows[0] == "step,seconds,hole,total,adv"
    assert [r.split(",")[0] for r in rows[1:]] == ["1", "2", "3"]
    assert rows[1].endswith(",") and rows[3].endswith(",0.3")
