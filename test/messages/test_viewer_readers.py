"""A replayed bag as a viewer reads it: Foxglove's own MCAP and ROS 2 readers (npm, test/viewer) decode every
message of every topic, the same values as rosbags; the 3-D scene of one moment drawn from those values."""
from __future__ import annotations

import dataclasses
import json
import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader
from scene_checks import check_outline, check_scene, check_static_tf
from scene_picture import render
from scipy.spatial.transform import Rotation
from simbags import encoder_tracking_plant

from cable_winch_monitor.bagio.typestore import typestore
from cable_winch_monitor.messages.outputs import OUTLINE, OUTPUT_TYPES, SCENE, TF, TF_STATIC
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.model.statics.result import solved
from cable_winch_monitor.monitor.alarm import AlarmLevel
from cable_winch_monitor.paths import demo_bag
from cable_winch_monitor.replay import replay

ROOT = Path(__file__).resolve().parents[2]
VIEWER = ROOT / "test" / "viewer"
PICTURE = ROOT / "build" / "viewer" / "scene.png"  # docs/scene.png is a copy
FOXGLOVE_LAYOUT = ROOT / "config" / "foxglove" / "cable_winch_monitor.json"
RVIZ_CONFIG = ROOT / "config" / "rviz" / "cable_winch_monitor.rviz"
SCRIPT_TOPIC = "/studio_script/residuals_sigma"  # the layout's user script: /model/residuals by channel


def plain(value):
    """A rosbags message as the JSON the Node reader prints: nested dicts, lists, NaN and infinities as text."""
    if dataclasses.is_dataclass(value):  # ROS 2 field names are lower case; constants and __msgtype__ are not
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value) if f.name.islower()
                and not f.name.startswith("__")}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [plain(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("Infinity" if value > 0 else "-Infinity")
    return value


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    """The bundled all-channels recording (lowering, stop, hoist; winch 4 lagging) replayed on the bundled plant
    tracking its encoders' offsets (so that every output topic is written), read by Foxglove's readers and by
    rosbags."""
    node = shutil.which("node")
    assert node and (VIEWER / "node_modules").is_dir(), "make setup-test installs Node and test/viewer's packages"
    out = tmp_path_factory.mktemp("viewer") / "replayed"
    summary = replay(demo_bag(), out, encoder_tracking_plant(out.parent), progress=False)
    (mcap,) = out.glob("*.mcap")
    result = subprocess.run([node, str(VIEWER / "read_bag.mjs"), str(mcap), "all"], capture_output=True, text=True,
                            timeout=120, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    store = typestore()
    with Reader(out) as reader:
        ours = [(c.topic, c.msgtype, t, store.deserialize_cdr(raw, c.msgtype)) for c, t, raw in reader.messages()]
    return summary, json.loads(result.stdout)["topics"], ours


def test_every_message_of_every_topic_decodes_with_foxglove_readers(replayed):
    summary, foxglove, ours = replayed
    counts = {topic: sum(t == topic for t, *_ in ours) for topic in {t for t, *_ in ours}}
    assert set(OUTPUT_TYPES) <= set(counts), "every output topic is in the bag"
    assert {topic: info["messages"] for topic, info in foxglove.items()} == counts
    for topic, info in foxglove.items():
        assert info["decoded"] == info["messages"] and not info["errors"], (topic, info["errors"])
        assert info["schemaEncoding"] == "ros2msg" and info["messageEncoding"] == "cdr"
    assert foxglove[TF]["schema"] == foxglove[TF_STATIC]["schema"] == "tf2_msgs/msg/TFMessage"
    assert foxglove[SCENE]["schema"] == foxglove[OUTLINE]["schema"] == "visualization_msgs/msg/MarkerArray"
    assert counts[TF_STATIC] == counts[OUTLINE] == 1 and counts[TF] == summary.stats.solved and counts[SCENE] >= 90


def test_foxglove_reads_the_values_rosbags_reads(replayed):
    _, foxglove, ours = replayed
    for topic, info in foxglove.items():
        mine = [(t, plain(m)) for name, _, t, m in ours if name == topic]
        theirs = [(v["logTime"], v["message"]) for v in info["values"]]
        assert theirs == mine, f"{topic}: Foxglove's readers decode other values"


def test_scene_of_the_lag_drawn_from_what_foxglove_read(replayed):
    """The moment winch 4 lags most: cable 3 carries least (its load pin reads about a kilonewton: the
    elastic ropes' truth keeps all four taut, and the monitor follows the pins); the scene checked and drawn."""
    _, foxglove, ours = replayed
    plant = load_plant()
    check_static_tf(next(m for topic, _, _, m in ours if topic == TF_STATIC), plant)
    check_outline(next(m for topic, _, _, m in ours if topic == OUTLINE), plant)
    tensions = {int(t): m for topic, _, t, m in ours if topic == "/cables/tension"}
    alarms = {int(t): m for topic, _, t, m in ours if topic == "/platform/collision_alarm"}
    poses = {int(t): m.pose for topic, _, t, m in ours if topic == "/platform/pose"}
    scenes = {int(v["logTime"]): v["message"] for v in foxglove[SCENE]["values"]}
    transforms = {int(v["logTime"]): v["message"]["transforms"][0] for v in foxglove[TF]["values"]}

    moment = min(scenes, key=lambda t: tensions[t].cables[2].tension)
    cables = tensions[moment].cables
    assert all(c.taut for c in cables) and 300.0 < cables[2].tension < 3000.0
    assert "tilt measured" in alarms[moment].reason
    pose = poses[moment]
    q = pose.orientation
    rotation = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    position = np.array([pose.position.x, pose.position.y, pose.position.z])
    published = solved(plant, "estimate", np.array([c.length for c in cables]), rotation, position,
                       np.array([c.tension for c in cables]), np.array([c.taut for c in cables]), 0)
    check_scene(next(m for topic, _, t, m in ours if topic == SCENE and t == moment), plant, published,
                AlarmLevel(alarms[moment].level), alarms[moment].clearance)
    render(scenes[moment], foxglove[OUTLINE]["values"][0]["message"], transforms[moment], PICTURE)
    assert PICTURE.stat().st_size > 20_000


def resolve(message, path: str):
    """A Foxglove message path's value in a decoded message (fields and [index] only, as the layout uses)."""
    value = message
    for name, index in re.findall(r"\.(\w+)|\[(\d+)\]", path):
        value = value[name] if name else value[int(index)]
    return value


def test_foxglove_layout_plots_what_the_bag_holds(replayed):
    _, foxglove, ours = replayed
    layout = json.loads(FOXGLOVE_LAYOUT.read_text())
    panels = layout["configById"]
    scene = panels["3D!scene"]
    assert scene["followTf"] == "platform" and set(scene["topics"]) <= set(foxglove)
    assert {topic for topic, shown in scene["topics"].items() if shown["visible"]} == {SCENE, OUTLINE}
    plotted = [p["value"] for key, panel in panels.items() if key.startswith("Plot!") for p in panel["paths"]]
    assert {"/cables/tension", "/platform/collision_alarm", SCRIPT_TOPIC} == {p.split(".")[0] for p in plotted}
    for path in plotted:
        topic, rest = path.split(".", 1)
        if topic == SCRIPT_TOPIC:
            continue
        values = [resolve(v["message"], "." + rest) for v in foxglove[topic]["values"]]
        assert values and all(isinstance(v, (int, float)) for v in values), path
    script = next(iter(layout["userNodes"].values()))["sourceCode"]
    assert f'output = "{SCRIPT_TOPIC}"' in script and 'inputs = ["/model/residuals"]' in script
    channels = {name for v in foxglove["/model/residuals"]["values"] for name in v["message"]["channels"]}
    assert all(f"{channel}: number" in script for channel in channels), "the script knows every residual channel"
    assert {p.split(".", 1)[1] for p in plotted if p.startswith(SCRIPT_TOPIC)} == channels
    assert {panels[k]["topicToRender"] for k in panels if k.startswith("Diagnostic")} == {"/diagnostics"}


def test_rviz_config_shows_the_scene_in_the_shaft_frame(replayed):
    _, foxglove, _ = replayed
    config = yaml.safe_load(RVIZ_CONFIG.read_text())["Visualization Manager"]
    transforms = [t for v in foxglove[TF]["values"] for t in v["message"]["transforms"]]
    assert config["Global Options"]["Fixed Frame"] == transforms[0]["header"]["frame_id"] == "shaft"
    assert config["Views"]["Current"]["Target Frame"] == transforms[0]["child_frame_id"] == "platform"
    displays = {d["Class"]: d for d in config["Displays"]}
    expected = {"rviz_default_plugins/MarkerArray": "visualization_msgs/msg/MarkerArray",
                "rviz_default_plugins/Pose": "geometry_msgs/msg/PoseStamped"}
    for kind, schema in expected.items():
        assert foxglove[displays[kind]["Topic"]["Value"]]["schema"] == schema
    arrays = [d for d in config["Displays"] if d["Class"] == "rviz_default_plugins/MarkerArray"]
    assert {d["Topic"]["Value"] for d in arrays} == {SCENE, OUTLINE}
    for display in arrays:
        topic = display["Topic"]["Value"]
        namespaces = {m["ns"] for v in foxglove[topic]["values"] for m in v["message"]["markers"]} - {""}
        assert set(display["Namespaces"]) == namespaces
        latched = display["Topic"]["Durability Policy"] == "Transient Local"
        assert latched == (topic == OUTLINE), "the outline comes once: RViz must ask for it latched"
    assert "rviz_default_plugins/TF" in displays
