"""The monitor's output topics and their message types (docs/interface.md): what the node publishes and replay
writes."""
from __future__ import annotations

MSGS = "cable_winch_monitor_msgs/msg"
POSE, TENSION, ALARM, RESIDUALS = "/platform/pose", "/cables/tension", "/platform/collision_alarm", "/model/residuals"
MODEL_ERROR, PARAMETERS = "/model/error", "/model/parameters"
TF, TF_STATIC, SCENE, OUTLINE = "/tf", "/tf_static", "/platform/scene", "/platform/outline"
DIAGNOSTICS = "/diagnostics"
OUTPUT_TYPES = {POSE: "geometry_msgs/msg/PoseStamped", TENSION: f"{MSGS}/TensionDistribution",
                ALARM: f"{MSGS}/CollisionAlarm", RESIDUALS: f"{MSGS}/ModelResiduals", MODEL_ERROR: f"{MSGS}/ModelError",
                PARAMETERS: f"{MSGS}/ModelParameters",
                TF: "tf2_msgs/msg/TFMessage", TF_STATIC: "tf2_msgs/msg/TFMessage",
                SCENE: "visualization_msgs/msg/MarkerArray", OUTLINE: "visualization_msgs/msg/MarkerArray",
                DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray"}

Record = tuple[str, str, bytes]  # topic, message type, CDR bytes: one output as written and published
