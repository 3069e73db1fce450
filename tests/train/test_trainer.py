"""The trainer: losses go down, checkpoints round-trip, runs resume, weights export."""

from __future__ import annotations

import csv
import zipfile

import numpy as np
import pytest
from trainkit import CROP, REGION_SIZE, SMALL, write_fake_vgg, write_folder

torch = pytest.importorskip("torch")

from photo3d.errors import ConfigError, InputError  # noqa: E402
from photo3d.nets import load_inpainting_nets  # noqa: E402
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


@pytest.fixture(autouse=True)
def one_thread():
    """Tiny nets run fastest (and steadiest on a shared machine) on one thread."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(autouse=True)
def fake_vgg(tmp_path_factory, monkeypatch):
    cache = tmp_path_factory.mktemp("cache")
    write_fake_vgg(cache)
    monkeypatch.setenv("PHOTO3D_CACHE", str(cache))


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    folder = write_folder(tmp_path_factory.mktemp("train"))
    files = find_training_files(folder / "images", depth=folder / "depth")
    return prepare_data(files, crop=CROP, region_size=REGION_SIZE)


def config(kind: str, **changes) -> TrainConfig:
    return TrainConfig(kind, **{**SMALL[kind], "size": CROP, "batch": 4, **changes})


@pytest.mark.parametrize("kind", ["edge", "depth", "color"])
def test_losses_are_finite_and_decrease_on_a_fixed_batch(data, kind):
    trainer = Trainer(config(kind, lr=1e-3), device="cpu")
    batch = to_tensors(make_batch(data, kind, size=CROP, batch=4, seed=0, step=1), trainer.device)
    history = [trainer.step(batch)[0] for _ in range(8)]
    totals = [h["total"] for h in history]
    assert all(np.isfinite(v) for h in history for v in h.values())
    assert totals[-1] < totals[0] and np.mean(totals[-3:]) < np.mean(totals[:3])
    if kind == "edge":
        assert {"adv", "fm", "d_total", "d_real", "d_fake"} <= set(history[0])


@pytest.mark.parametrize("kind", ["edge", "depth", "color"])
def test_checkpoint_save_load_gives_identical_outputs(data, kind, tmp_path):
    a = Trainer(config(kind, seed=1), device="cpu")
    batch = to_tensors(make_batch(data, kind, size=CROP, batch=4, seed=0, step=1), a.device)
    a.step(batch)
    a.save(tmp_path / "ckpt", step=1)
    b = Trainer(config(kind, seed=2), device="cpu")  # other initial weights
    assert b.load(tmp_path / "ckpt") == 1
    a.net.eval(), b.net.eval()
    with torch.no_grad():
        torch.testing.assert_close(a.net(batch["inputs"]), b.net(batch["inputs"]),
                                   rtol=0, atol=0)
    # one more step from the same state gives the same weights (optimiser restored)
    a.net.train(), b.net.train()
    la, _ = a.step(batch)
    lb, _ = b.step(batch)
    assert la == pytest.approx(lb, rel=1e-5)
    for (name, p), q in zip(a.net.named_parameters(), b.net.parameters(), strict=True):
        torch.testing.assert_close(p, q, msg=name)
    # the exported weights are what the learned inpainter loads
    a.export(tmp_path / f"{kind}.safetensors")
    loaded, source = load_net(kind, tmp_path)
    a.net.eval()
    with torch.no_grad():
        torch.testing.assert_close(loaded(batch["inputs"]), a.net(batch["inputs"]),
                                   rtol=0, atol=0)
    assert source == "safetensors"


def _tampered(state: dict, how: str) -> dict:
    first = state["generator"]["state"][0]
    if how == "shape":
        first["exp_avg"] = torch.zeros(7)
    elif how == "nan":
        first["exp_avg_sq"] = torch.full_like(first["exp_avg_sq"], float("nan"))
    elif how == "negative step":
        first["step"] = torch.tensor(-5.0)
    elif how == "compressed":
        return state
    elif how == "no state":
        state["generator"] = {"param_groups": state["generator"]["param_groups"]}
    else:
        state["generator"] = 5
    return state


@pytest.mark.parametrize("how", ["shape", "nan", "negative step", "no state", "not a dict",
                                 "compressed"])
def test_a_tampered_optimizer_state_is_one_line(data, tmp_path, how):
    """A torch file of the right form but wrong contents failed with a traceback (at
    load, or at the first step)."""
    a = Trainer(config("depth"), device="cpu")
    batch = to_tensors(make_batch(data, "depth", size=CROP, batch=4, seed=0, step=1), a.device)
    a.step(batch)
    a.save(tmp_path / "ckpt", step=1)
    path = tmp_path / "ckpt" / "optimizer.pt"
    torch.save(_tampered(torch.load(path, weights_only=True), how), path)
    if how == "compressed":  # torch.load would inflate it: a zip bomb's form
        with zipfile.ZipFile(path) as zin:
            records = [(info.filename, zin.read(info)) for info in zin.infolist()]
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zout:
            for name, data in records:
                zout.writestr(name, data)
    b = Trainer(config("depth"), device="cpu")
    with pytest.raises(InputError, match=r"^cannot read .*optimizer.pt: not a checkpoint "
                                         r"photo3d train wrote"):
        b.load(tmp_path / "ckpt")


def test_a_resumed_run_uses_its_own_learning_rate(tmp_path):
    Trainer(config("depth", lr=1e-4), device="cpu").save(tmp_path / "ckpt", step=1)
    b = Trainer(config("depth", lr=1e-3), device="cpu")
    b.load(tmp_path / "ckpt")
    assert b.optimizer.param_groups[0]["lr"] == 1e-3  # as config.json says


def test_a_run_resumes_where_it_stopped_and_exports_loadable_weights(data, tmp_path):
    run = tmp_path / "run"
    first = train(data, run, config("depth", steps=2, checkpoint_every=1), device="cpu")
    assert (first.start_step, first.step) == (0, 2)
    assert [s for s, _ in checkpoints(run)] == [1, 2]
    second = train(data, run, config("depth", steps=5, checkpoint_every=2, sample_every=2),
                   device="cpu")
    assert (second.start_step, second.step) == (2, 5)
    assert [s for s, _ in checkpoints(run)] == [4, 5]  # the last two are kept
    with open(run / "losses.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["step"]) for r in rows] == [1, 2, 3, 4, 5]
    assert set(rows[0]) == {"step", "seconds", "context", "synthesis", "total"}
    assert sorted(p.name for p in (run / "samples").iterdir()) == [
        "step_0000002.png", "step_0000004.png", "step_0000005.png"]
    # a run continued in one go sees the same data: steps 3..5 match a fresh 5-step run
    fresh = train(data, tmp_path / "fresh", config("depth", steps=5), device="cpu")
    assert fresh.losses == pytest.approx(second.losses, rel=1e-4)
    with pytest.raises(ConfigError, match="holds a depth run with levels 3, not 4"):
        train(data, run, config("depth", steps=6, levels=4), device="cpu")


def test_an_interrupted_checkpoint_leaves_the_complete_ones_and_no_temporaries(
        data, tmp_path, monkeypatch):
    run = tmp_path / "run"
    train(data, run, config("depth", steps=2, checkpoint_every=1), device="cpu")
    real_save = Trainer.save

    def interrupted(self, folder, step):
        real_save(self, folder, step)  # written completely: Ctrl-C before the rename
        raise KeyboardInterrupt

    monkeypatch.setattr(Trainer, "save", interrupted)
    with pytest.raises(KeyboardInterrupt):
        train(data, run, config("depth", steps=4, checkpoint_every=1), device="cpu")
    assert [s for s, _ in checkpoints(run)] == [1, 2]
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == [
        "step_0000001", "step_0000002"]
    assert not [p for p in run.rglob(".*")], "a temporary file or folder was left"
    monkeypatch.undo()
    # the loss log was truncated to the checkpoint, atomically, and the run resumes
    resumed = train(data, run, config("depth", steps=4, checkpoint_every=1), device="cpu")
    assert (resumed.start_step, resumed.step) == (2, 4)
    with open(run / "losses.csv", newline="") as f:
        assert [int(r["step"]) for r in csv.DictReader(f)] == [1, 2, 3, 4]
    assert not [p for p in run.rglob(".*")]


def test_the_three_exported_nets_load_as_the_learned_inpainter(data, tmp_path):
    for kind in ("edge", "depth", "color"):
        r = train(data, tmp_path / kind, config(kind, steps=1, batch=2), device="cpu")
        (tmp_path / "weights").mkdir(exist_ok=True)
        r.weights.rename(tmp_path / "weights" / r.weights.name)
    nets = load_inpainting_nets(tmp_path / "weights", device="cpu")
    assert nets.sources == {k: "safetensors" for k in ("edge", "depth", "color")}


def test_config_is_checked():
    with pytest.raises(ConfigError, match="multiple of 128"):
        TrainConfig("color", size=96)
    with pytest.raises(ConfigError, match="unknown net"):
        TrainConfig("normals")
    with pytest.raises(ConfigError, match="gan must be"):
        TrainConfig("edge", gan="wgan")
    for changes in ({"width": float("inf")}, {"lr": float("inf")}, {"width": float("nan")}):
        with pytest.raises(ConfigError, match="width and lr must be positive and finite"):
            TrainConfig("edge", **changes)  # an infinite width was an OverflowError
    assert TrainConfig("edge", size=100).working_size == 400
