"""The interface package msg_defs/ is built into .venv and its types really work.

Real compiled rosidl types (C type support via rclpy), no mocks: each message and
the service request/response is filled, serialised to CDR and back, and compared.
"""
import array
import math

import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose, Quaternion
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header

from cable_winch_monitor_msgs.msg import (
    CableTension,
    CollisionAlarm,
    ModelResiduals,
    TensionDistribution,
)
from cable_winch_monitor_msgs.srv import CheckCableLengths


def same(a, b):
    """Field-by-field equality of two ROS messages (NaN equals NaN)."""
    if hasattr(a, 'get_fields_and_field_types'):
        assert type(a) is type(b)
        return all(same(getattr(a, f), getattr(b, f)) for f in a.get_fields_and_field_types())
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, (list, tuple, array.array)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


def roundtrip(msg):
    data = serialize_message(msg)
    assert isinstance(data, bytes) and len(data) > 4
    back = deserialize_message(data, type(msg))
    assert back is not msg
    assert same(msg, back), f'{msg!r} != {back!r}'
    return back


def header(sec=1700000000, nanosec=123456789, frame='shaft'):
    return Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame)


def cable(i, tension, taut):
    return CableTension(name=f'cable_{i}', length=10.0 + 0.25 * i, span=9.875 + 0.25 * i,
                        tension=tension, taut=taut)


def tension_distribution():
    return TensionDistribution(
        header=header(),
        status=TensionDistribution.STATUS_SOLVED,
        tension_state='taut {1,2,4}',
        cables=[cable(1, 1234.5, True), cable(2, 987.25, True),
                cable(3, 0.0, False), cable(4, 1500.125, True)],
        equilibrium_residual=1.5e-12,
        solver='energy',
        iterations=42,
        sensors_used=['tension_cable_1', '/platform/imu'],
        length_corrections_sigma=[0.5, -1.25, 0.0, 2.0],
    )


def collision_alarm():
    return CollisionAlarm(
        header=header(frame='shaft'),
        level=CollisionAlarm.LEVEL_WARNING,
        clearance=-0.0125,
        closest_point_name='deck_1/p3',
        closest_point_platform=Point(x=1.2, y=-0.8, z=0.0),
        closest_point_shaft=Point(x=1.25, y=-0.75, z=-35.5),
        sync_error_pairs=['cable_1-cable_2', 'cable_1-cable_3', 'cable_3-cable_4'],
        sync_errors=[0.01, -0.002, 1e-6],
        reason='clearance below warning margin',
    )


def test_constants():
    assert TensionDistribution.STATUS_SOLVED == 0
    assert TensionDistribution.STATUS_SINGLE_CABLE_INDETERMINATE == 1
    assert TensionDistribution.STATUS_NO_EQUILIBRIUM == 2
    assert TensionDistribution.STATUS_INVALID_INPUT == 3
    assert TensionDistribution.STATUS_SOLVER_FAILED == 4
    assert [CollisionAlarm.LEVEL_OK, CollisionAlarm.LEVEL_WARNING,
            CollisionAlarm.LEVEL_CRITICAL, CollisionAlarm.LEVEL_COLLISION] == [0, 1, 2, 3]


def test_field_types():
    assert CableTension.get_fields_and_field_types() == {
        'name': 'string', 'length': 'double', 'span': 'double', 'tension': 'double',
        'taut': 'boolean'}
    assert TensionDistribution.get_fields_and_field_types() == {
        'header': 'std_msgs/Header', 'status': 'uint8', 'tension_state': 'string',
        'cables': 'sequence<cable_winch_monitor_msgs/CableTension>',
        'equilibrium_residual': 'double', 'solver': 'string', 'iterations': 'uint32',
        'sensors_used': 'sequence<string>', 'length_corrections_sigma': 'sequence<double>'}
    assert CollisionAlarm.get_fields_and_field_types() == {
        'header': 'std_msgs/Header', 'level': 'uint8', 'clearance': 'double',
        'closest_point_name': 'string', 'closest_point_platform': 'geometry_msgs/Point',
        'closest_point_shaft': 'geometry_msgs/Point', 'sync_error_pairs': 'sequence<string>',
        'sync_errors': 'sequence<double>', 'reason': 'string'}
    assert ModelResiduals.get_fields_and_field_types() == {
        'header': 'std_msgs/Header', 'channels': 'sequence<string>',
        'measured': 'sequence<double>', 'predicted': 'sequence<double>',
        'residuals': 'sequence<double>', 'noise': 'sequence<double>'}
    assert CheckCableLengths.Request.get_fields_and_field_types() == {
        'names': 'sequence<string>', 'lengths': 'sequence<double>'}
    assert CheckCableLengths.Response.get_fields_and_field_types() == {
        'accepted': 'boolean', 'message': 'string', 'pose': 'geometry_msgs/Pose',
        'tension': 'cable_winch_monitor_msgs/TensionDistribution',
        'alarm': 'cable_winch_monitor_msgs/CollisionAlarm'}


def test_cable_tension_roundtrip():
    back = roundtrip(cable(3, 0.0, False))
    assert back.name == 'cable_3' and back.length == 10.75 and back.span == 10.625
    assert back.tension == 0.0 and back.taut is False


@pytest.mark.parametrize('status, state', [
    (TensionDistribution.STATUS_SOLVED, 'taut {1,2,4}'),
    (TensionDistribution.STATUS_SINGLE_CABLE_INDETERMINATE, 'single cable 1: pose indeterminate'),
    (TensionDistribution.STATUS_NO_EQUILIBRIUM, 'no equilibrium'),
])
def test_tension_distribution_roundtrip(status, state):
    msg = tension_distribution()
    msg.status, msg.tension_state = status, state
    back = roundtrip(msg)
    assert back.header.stamp.sec == 1700000000 and back.header.stamp.nanosec == 123456789
    assert back.header.frame_id == 'shaft'
    assert [c.name for c in back.cables] == ['cable_1', 'cable_2', 'cable_3', 'cable_4']
    assert [c.taut for c in back.cables] == [True, True, False, True]
    assert back.cables[3].tension == 1500.125
    assert back.iterations == 42 and back.solver == 'energy'


def test_tension_distribution_empty_roundtrip():
    roundtrip(TensionDistribution())


def test_collision_alarm_roundtrip():
    back = roundtrip(collision_alarm())
    assert back.level == CollisionAlarm.LEVEL_WARNING
    assert back.clearance == -0.0125
    assert back.closest_point_shaft.z == -35.5
    assert list(back.sync_error_pairs) == ['cable_1-cable_2', 'cable_1-cable_3', 'cable_3-cable_4']
    assert list(back.sync_errors) == [0.01, -0.002, 1e-6]
    roundtrip(CollisionAlarm())


def test_model_residuals_roundtrip():
    msg = ModelResiduals(
        header=header(sec=5, nanosec=0, frame='shaft'),
        channels=['tension_cable_1', 'roll', 'pitch', 'depth'],
        measured=[1000.0, 0.01, -0.02, -35.0],
        predicted=[990.0, 0.0125, -0.0195, -35.02],
        residuals=[10.0, 0.01 - 0.0125, -0.02 + 0.0195, -35.0 + 35.02],
        noise=[5.0, 0.001, 0.001, float('nan')],
    )
    back = roundtrip(msg)
    assert list(back.channels) == ['tension_cable_1', 'roll', 'pitch', 'depth']
    assert list(back.residuals) == list(msg.residuals)
    assert math.isnan(back.noise[3]) and back.noise[0] == 5.0
    roundtrip(ModelResiduals())


def test_check_cable_lengths_service_roundtrip():
    req = CheckCableLengths.Request(names=['cable_1', 'cable_2', 'cable_3', 'cable_4'],
                                    lengths=[10.0, 10.0, 10.01, 9.99])
    back = roundtrip(req)
    assert list(back.lengths) == [10.0, 10.0, 10.01, 9.99]
    roundtrip(CheckCableLengths.Request())

    resp = CheckCableLengths.Response(
        accepted=True,
        message='equilibrium with 3 taut cables',
        pose=Pose(position=Point(x=0.001, y=-0.002, z=-35.0),
                  orientation=Quaternion(x=0.0, y=0.0087, z=0.0, w=0.99996)),
        tension=tension_distribution(),
        alarm=collision_alarm(),
    )
    back = roundtrip(resp)
    assert back.accepted is True
    assert back.pose.position.z == -35.0
    assert back.tension.cables[1].tension == 987.25
    assert back.alarm.closest_point_name == 'deck_1/p3'
    roundtrip(CheckCableLengths.Response())


def test_service_type_support():
    """The service class is usable by rclpy (type support loads from .venv/lib)."""
    from rclpy.type_support import check_for_type_support
    for t in (CableTension, TensionDistribution, CollisionAlarm, ModelResiduals, CheckCableLengths):
        check_for_type_support(t)
    assert CheckCableLengths.Request.__name__.endswith('Request')
    assert CheckCableLengths.Response.__name__.endswith('Response')
