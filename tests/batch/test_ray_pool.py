"""The Ray engine's scheduling (``ray_engine._Pool``) against a stand-in for Ray: a
cluster of a few one-CPU slots where an actor starts only when a slot is free, and
where losing a node takes its slot away. Runs without ray, in well under a second."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from photo3d.batch import ray_engine
from photo3d.batch.jobs import PhotoJob
from photo3d.batch.manifest import PhotoResult


class RayError(Exception):
    pass


class Ref:
    def __init__(self, value=None, error: BaseException | None = None, ready: bool = True):
        self.value, self.error, self.ready = value, error, ready


class FakeRay:
    """Just enough of ``ray`` for ``_Pool``: actors, their calls, ``wait``, ``kill``."""

    exceptions = SimpleNamespace(RayError=RayError)

    def __init__(self, cpus: int, *, lost: tuple[str, ...] = (), broken_starts: int = 0):
        self.cpus = cpus  # the cluster's slots
        self.lost = set(lost)  # photos whose node dies under them (first time only)
        self.broken_starts = broken_starts  # how many actors die while starting
        self.actors: list[FakeActor] = []
        self.made: list[tuple[str, int]] = []  # (photo, actor number)
        self.timeouts: list[float | None] = []

    def holding(self) -> int:
        return sum(a.state == "started" for a in self.actors)

    def schedule(self) -> None:
        """Start pending actors while the cluster has free slots."""
        for actor in self.actors:
            if actor.state == "pending" and self.holding() < self.cpus:
                actor.state = "started"
                if self.broken_starts:
                    self.broken_starts -= 1
                    actor.state = "dead"
                    actor.where_ref.error = RayError("ActorDiedError: died starting")
                actor.where_ref.ready = True

    def wait(self, refs, *, num_returns=1, timeout=None):
        self.timeouts.append(timeout)
        self.schedule()
        done = [r for r in refs if r.ready][:num_returns]
        if not done and timeout is None:
            raise AssertionError("ray.wait would wait forever: nothing can finish")
        return done, [r for r in refs if r not in done]

    def get(self, ref, timeout=None):
        assert ref.ready
        if ref.error is not None:
            raise ref.error
        return ref.value

    def kill(self, actor) -> None:
        actor.state = "dead"

    def cluster_resources(self) -> dict:
        return {"CPU": float(self.cpus)} if self.cpus else {}


class FakeActor:
    def __init__(self, ray: FakeRay) -> None:
        self.ray, self.number, self.state = ray, len(ray.actors), "pending"
        self.where_ref = Ref(("elsewhere", 1), ready=False)
        self.where = SimpleNamespace(remote=lambda: self.where_ref)
        self.make = SimpleNamespace(remote=self._make)
        ray.actors.append(self)

    def _make(self, job: PhotoJob, out: str) -> Ref:
        assert self.state == "started", "a photo sent to an actor that has not started"
        if job.name in self.ray.lost:  # its node dies: one slot fewer in the cluster
            self.ray.lost.discard(job.name)
            self.state = "dead"
            self.ray.cpus -= 1
            return Ref(error=RayError("ActorDiedError: The actor died because its node "
                                      "has died."))
        self.ray.made.append((job.name, self.number))
        return Ref(PhotoResult(job.name, "ok", None, 1.0, f"{out}/{job.name}"))


def pool(ray: FakeRay, count: int):
    return ray_engine._Pool(ray, SimpleNamespace(remote=lambda *a: FakeActor(ray)), count, ())


@pytest.fixture(autouse=True)
def no_waiting(monkeypatch):
    monkeypatch.setattr(ray_engine, "_REMOTE_S", 0.0)
    monkeypatch.setattr(ray_engine, "_NO_CPU_S", 0.0)


def jobs(count: int) -> list[PhotoJob]:
    return [PhotoJob(f"p{i}", None) for i in range(count)]


def test_a_node_lost_under_a_photo_leaves_its_photo_to_the_actors_left(tmp_path):
    """Two one-CPU nodes; p0's node dies. Its replacement actor has no CPU while the
    other actor holds the last one: p0 must go to that actor, not wait forever."""
    ray = FakeRay(2, lost=("p0",))
    results: list[PhotoResult] = []
    pool(ray, 2).run(jobs(4), tmp_path, results.append)
    assert sorted((r.name, r.status) for r in results) == [
        ("p0", "ok"), ("p1", "ok"), ("p2", "ok"), ("p3", "ok")]
    assert len({n for _, n in ray.made}) == 1  # all on the actor left
    assert all(a.state == "dead" for a in ray.actors)  # none left running at the end


def test_photos_go_only_to_started_actors_and_idle_ones_are_released(tmp_path):
    """Four photos, a pool of three on a cluster of two CPUs: the third actor never
    starts; everything is made by the two that did, and the third is killed."""
    ray = FakeRay(2)
    results: list[PhotoResult] = []
    pool(ray, 3).run(jobs(4), tmp_path, results.append)
    assert [r.status for r in results] == ["ok"] * 4
    assert {n for _, n in ray.made} <= {0, 1}  # (_make checks each actor had started)
    assert [a.state for a in ray.actors] == ["dead"] * 3  # the third killed, never started


def test_a_cluster_without_cpus_fails_the_photos_left(tmp_path):
    """The only node dies under p0; its replacement can never start: p0 and the photos
    after it are recorded as failed instead of waited for."""
    ray = FakeRay(1, lost=("p0",))
    results: list[PhotoResult] = []
    pool(ray, 1).run(jobs(3), tmp_path, results.append)
    assert [(r.name, r.status) for r in results] == [
        ("p0", "failed"), ("p1", "failed"), ("p2", "failed")]
    assert all(r.error == "the Ray cluster has no CPU left" for r in results)
    assert all(t is not None for t in ray.timeouts)  # never a wait without a time limit


def test_actors_dying_as_they_start_end_in_failed_photos_not_a_loop(tmp_path):
    ray = FakeRay(2, broken_starts=100)
    results: list[PhotoResult] = []
    pool(ray, 2).run(jobs(3), tmp_path, results.append)
    assert [r.status for r in results] == ["failed"] * 3
    assert "no Ray actor could start" in results[0].error
    assert len(ray.actors) <= 2 + 2 + ray_engine._START_FAILURES  # a few, then no more


def test_a_broken_start_beside_working_actors_costs_no_photo(tmp_path):
    """The first actors die starting; the ones that start make every photo."""
    ray = FakeRay(2, broken_starts=3)
    results: list[PhotoResult] = []
    pool(ray, 2).run(jobs(5), tmp_path, results.append)
    assert [r.status for r in results] == ["ok"] * 5


def test_a_new_local_ray_is_started_even_beside_a_running_one(monkeypatch):
    # ray.init() without an address joins a Ray already running on the machine (and
    # then refuses num_cpus): photo3d asks for a new local one ("local")
    from types import SimpleNamespace

    from photo3d.batch import ray_engine

    calls = []
    fake = SimpleNamespace(is_initialized=lambda: False,
                           init=lambda **kwargs: calls.append(kwargs))
    monkeypatch.setattr(ray_engine, "require_ray", lambda: fake)
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    assert ray_engine.connect(local_cpus=2) == "local"
    assert calls[0]["address"] == "local" and calls[0]["num_cpus"] == 2
    assert ray_engine.connect("10.0.0.1:6379") == "10.0.0.1:6379"
    assert calls[1]["address"] == "10.0.0.1:6379" and "num_cpus" not in calls[1]
