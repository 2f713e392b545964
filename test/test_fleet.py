"""Fleet replay and diagnose: a folder of bags on worker processes and on a local Dask cluster, one summary table.

The Dask cluster runs on this machine only (127.0.0.1, two worker processes, no
dashboard); its results and output bags must equal a single-process run's.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from simbags import assert_clean, run_cli

from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.fleet import diagnose_job, find_bags, is_fleet, replay_job, run_fleet
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.paths import demo_bag

BAGS = ("shaft_a", "shaft_b", "shaft_c")


@pytest.fixture(scope="module")
def fleet(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("fleet") / "bags"
    for name in BAGS:
        shutil.copytree(demo_bag(), folder / name)
    return folder


def count_messages(bag: Path, out: Path) -> dict:
    """A pluggable per-bag job (as a diagnose job would be): one row per bag."""
    return {"bag": bag.name, "messages": sum(1 for _ in BagReader(bag))}


def without_wall(rows):
    return [{k: v for k, v in row.items() if k != "wall [s]"} for row in rows]


def output_bag(path: Path):
    return [(m.topic, m.log_time, m.data) for m in BagReader(path)]


def test_folder_is_a_fleet(fleet):
    assert is_fleet(fleet) and not is_fleet(fleet / "shaft_a") and not is_fleet(demo_bag())
    assert [bag.name for bag in find_bags(fleet)] == list(BAGS)


def test_cli_workers_summary_table(fleet, tmp_path):
    result = run_cli("replay", fleet, "--out", tmp_path / "out", "--workers", "2")
    assert_clean(result, 0)
    lines = result.stdout.splitlines()
    assert [line.split()[0] for line in lines[1:5]] == [*BAGS, "total"]
    assert lines[4].split()[1] == str(3 * 2049)  # samples in total
    assert "3 bag(s) on 2 worker processes" in lines[-1]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == list(BAGS)


@pytest.mark.timeout(120)
def test_dask_cluster_gives_identical_results(fleet, tmp_path):
    distributed = pytest.importorskip("distributed")
    job = replay_job()
    local = run_fleet(find_bags(fleet), tmp_path / "local", job)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        remote = run_fleet(find_bags(fleet), tmp_path / "dask", job, scheduler=cluster.scheduler_address)
        custom = run_fleet(find_bags(fleet), tmp_path / "custom", count_messages, scheduler=cluster.scheduler_address)
    assert "Dask cluster tcp://127.0.0.1:" in remote.format()
    assert without_wall(remote.rows) == without_wall(local.rows) and remote.samples == 3 * 2049
    for name in BAGS:
        assert output_bag(tmp_path / "dask" / name) == output_bag(tmp_path / "local" / name)
    one = count_messages(fleet / BAGS[0], tmp_path)["messages"]
    assert custom.rows[0] == {"bag": BAGS[0], "messages": one} and custom.total() == {"bag": "total", "messages": 3 * one}


@pytest.fixture(scope="module")
def effect_fleet(tmp_path_factory) -> tuple[Path, Path]:
    """Two bags of the elastic-rope plant: one with the ropes' weight hidden in the truth, one with nothing."""
    from effectbags import ELASTIC, SEED002, plant_file, simulate_bag

    plant = plant_file(tmp_path_factory.mktemp("plant"), "nominal", SEED002, ELASTIC)
    bags = tmp_path_factory.mktemp("effect_fleet")  # the bags, and beside them their scenario files
    simulate_bag(bags, "heavy_ropes", plant, {"rope_weight": {"w": 60.0}})
    simulate_bag(bags, "as_modelled", plant, {})
    return bags, plant


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_fleet_diagnose_finds_each_bags_effect_on_workers_and_on_dask(effect_fleet, tmp_path):
    bags, plant = effect_fleet
    result = run_cli("diagnose", bags, "--config", plant, "--candidates", "rope_weight,encoder_offset",
                     "--workers", "2", "--out", tmp_path / "out", "--json", tmp_path / "table.json", timeout=240)
    assert_clean(result, 0)
    lines = result.stdout.splitlines()
    assert lines[0].split()[:2] == ["bag", "rows"]
    rows = {line.split()[0]: line for line in lines[1:4]}
    assert set(rows) == {"as_modelled", "heavy_ropes", "total"}
    assert "rope_weight" in rows["heavy_ropes"] and " - " in rows["as_modelled"]
    assert "2 bag(s) on 2 worker processes" in lines[-1]
    table = json.loads((tmp_path / "table.json").read_text())
    by_bag = {row["bag"]: row for row in table["bags"]}
    assert table["total"]["rows"] == sum(row["rows"] for row in table["bags"])
    assert by_bag["heavy_ropes"]["score after"] < by_bag["heavy_ropes"]["score"]  # the error falls
    for name in ("heavy_ropes", "as_modelled"):  # each bag's full result, as `diagnose --json` writes it
        report = json.loads((tmp_path / "out" / f"{name}.json").read_text())
        assert report["selected"] == (["rope_weight"] if name == "heavy_ropes" else [])
        assert report["samples"] == by_bag[name]["rows"]

    distributed = pytest.importorskip("distributed")
    job = diagnose_job(load_plant(plant), ["rope_weight", "encoder_offset"])
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        remote = run_fleet(find_bags(bags), tmp_path / "dask", job, scheduler=cluster.scheduler_address)
    assert without_wall(remote.rows) == without_wall(table["bags"])
