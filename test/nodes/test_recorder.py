"""`cable-winch-monitor record` over real DDS: raw bytes into a bag that closes cleanly on a signal."""
from __future__ import annotations

import signal
import subprocess
import time

import pytest
from ros_harness import TestClient, ros_env
from simbags import CLI

from cable_winch_monitor.bagio.reader import BagReader


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_record_until_signal(tmp_path, domain_id, stop):
    out = tmp_path / "recorded"
    recorder = subprocess.Popen([*CLI, "record", "--out", str(out), "/winch/joint_states", "/platform/imu",
                                 "/never/published"], env=ros_env(domain_id), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    client = TestClient(domain_id)
    try:
        deadline = time.monotonic() + 20.0
        while client.winch.get_subscription_count() == 0 or client.imu.get_subscription_count() == 0:
            assert recorder.poll() is None and time.monotonic() < deadline, "the recorder did not subscribe"
            time.sleep(0.05)
        time.sleep(0.5)
        # empty velocity and effort: the arrays rclpy's serialize_message would pad
        stamps = [client.publish((50.0 + 0.01 * k,) * 4) for k in range(20)]
        time.sleep(1.0)
    finally:
        client.close()
        recorder.send_signal(stop)
        stdout, stderr = recorder.communicate(timeout=20.0)
    assert recorder.returncode == 0 and "Traceback" not in stdout + stderr, stdout + stderr
    assert "recorded 20 messages" in stdout and "/never/published: never published" in stdout
    recorded = list(BagReader(out))
    assert [(m.message.header.stamp.sec, m.message.header.stamp.nanosec) for m in recorded] == [
        (s.sec, s.nanosec) for s in stamps]
    assert [m.message.position[0] for m in recorded] == [50.0 + 0.01 * k for k in range(20)]
    assert all(len(m.message.velocity) == 0 and m.topic == "/winch/joint_states" for m in recorded)
