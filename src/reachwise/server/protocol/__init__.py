"""Wire protocol of the collision server: versioned msgpack messages, strictly validated.

The collision server of the thesis (P-III §4.1 Fig. 2, P-IV, P-V §I–II) keeps the point
clouds, updates their poses from joint sensors and scans, and answers the control system
every cycle. This module is the language the two speak. One request and one reply are
each a single ZeroMQ frame holding one msgpack map:

- request ``{"v": 1, "id": <int>, "op": <str>, "body": <map>}``
- reply ``{"v": 1, "id": <int | nil>, "ok": true, "body": <map>}`` or
  ``{"v": 1, "id": <int | nil>, "ok": false, "error": {"code", "field", "message"}}``

The operations follow the phases of P-V Table 1: the *initialization phase* registers
robots (their YAML mapping, :func:`reachwise.io.robot_file.robot_to_dict`; never a
pickle) and part clouds, whose spatial indices the server builds once
(``add_robot``, ``add_object``, ``replace_cloud`` for a new scan, the ``watch*`` pair
rules); the *calculation phase* takes the inputs "object poses" — joint states the
server turns into link poses by forward kinematics, or run-time object poses
(``set_joints``, ``set_pose``) — and answers every watched pair (``query``).

Rules every decoder here follows (the server and the client alike):

- the frame's size is checked *before* decoding (:attr:`Limits.max_message_bytes`),
  and msgpack itself is given length limits, so a hostile frame cannot make it allocate;
- numpy arrays travel as ``[dtype, shape, bytes]`` (little-endian ``"<f8"`` floats,
  ``"<i8"`` integers, ``"|b1"`` booleans); the byte count must match the shape, and the
  row count of a cloud is checked against :attr:`Limits.max_cloud_points` before any
  array is made;
- every field is checked for presence, type, shape and finiteness; unknown fields are
  errors; nothing is ever unpickled or evaluated.

A bad message becomes a :class:`ProtocolError` with an :class:`ErrorCode` and the name
of the offending field, which the server sends back as a typed error reply.

Units are SI: lengths in metres, angles in radians, times in seconds. Time stamps are
readings of the *sender's* clock (by default :func:`time.monotonic`, shared by every
process on one host; clients on several hosts must share a synchronized clock).

The package: :mod:`~reachwise.server.protocol.fields` (limits, error codes, the field
checks), :mod:`~reachwise.server.protocol.requests`,
:mod:`~reachwise.server.protocol.replies` and :mod:`~reachwise.server.protocol.codec`
(frames, and the fast path of the per-tick messages); everything public is here.
"""

from __future__ import annotations

from reachwise.server.protocol.codec import (
    DecodedReply,
    decode_reply,
    decode_request,
    encode_error,
    encode_reply,
    encode_request,
)
from reachwise.server.protocol.fields import (
    BOOL,
    DEFAULT_LIMITS,
    FLOAT,
    INPUT_CODES,
    INT,
    MAX_CLOUD_POINTS,
    MAX_MESSAGE_BYTES,
    PROTOCOL_VERSION,
    SUPPORTED_VERSIONS,
    ErrorCode,
    Limits,
    ProtocolError,
    Reader,
    check_array,
    check_name,
    encode_array,
)
from reachwise.server.protocol.replies import (
    REPLIES,
    ROW_COLUMNS,
    Ack,
    DescribeReply,
    ErrorReply,
    HealthReply,
    HelloReply,
    MetricsReply,
    ObjectInfo,
    ObjectReply,
    PairInfo,
    PairsReply,
    PosesReply,
    QueryReply,
    Reply,
    RobotReply,
)
from reachwise.server.protocol.requests import (
    REQUESTS,
    AddObject,
    AddRobot,
    Clear,
    Describe,
    Health,
    Hello,
    Metrics,
    Poses,
    Query,
    ReplaceCloud,
    Request,
    SetJoints,
    SetPose,
    Unwatch,
    Watch,
    WatchEnvironment,
    WatchRobots,
    WatchSelf,
)

__all__ = [
    "BOOL",
    "DEFAULT_LIMITS",
    "FLOAT",
    "INPUT_CODES",
    "INT",
    "MAX_CLOUD_POINTS",
    "MAX_MESSAGE_BYTES",
    "PROTOCOL_VERSION",
    "REPLIES",
    "REQUESTS",
    "ROW_COLUMNS",
    "SUPPORTED_VERSIONS",
    "Ack",
    "AddObject",
    "AddRobot",
    "Clear",
    "DecodedReply",
    "Describe",
    "DescribeReply",
    "ErrorCode",
    "ErrorReply",
    "Health",
    "HealthReply",
    "Hello",
    "HelloReply",
    "Limits",
    "Metrics",
    "MetricsReply",
    "ObjectInfo",
    "ObjectReply",
    "PairInfo",
    "PairsReply",
    "Poses",
    "PosesReply",
    "ProtocolError",
    "Query",
    "QueryReply",
    "Reader",
    "ReplaceCloud",
    "Reply",
    "Request",
    "RobotReply",
    "SetJoints",
    "SetPose",
    "Unwatch",
    "Watch",
    "WatchEnvironment",
    "WatchRobots",
    "WatchSelf",
    "check_array",
    "check_name",
    "decode_reply",
    "decode_request",
    "encode_array",
    "encode_error",
    "encode_reply",
    "encode_request",
]
