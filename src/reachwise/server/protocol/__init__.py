"""Wire protocol of the collision server: versioned msgpack messages, strictly validated,
raw frames for clouds, and a binary frame for the per-tick query.

The collision server of the thesis (P-III §4.1 Fig. 2, P-IV, P-V §I–II) keeps the point
clouds, updates their poses from joint sensors and scans, and answers the control system
every cycle. This package is the language the two speak. A request and its reply are
ZeroMQ messages; most are a single frame holding one msgpack map:

- request ``{"v": 1, "id": <int>, "op": <str>, "body": <map>}``
- reply ``{"v": 1, "id": <int | nil>, "ok": true, "body": <map>}`` or
  ``{"v": 1, "id": <int | nil>, "ok": false, "error": {"code", "field", "message"}}``

Two kinds of message leave msgpack where it costs:

- **Streamed clouds** (``replace_cloud``: a new scan, a 30 Hz depth camera): the envelope
  is followed by one raw data frame holding the N x 3 points (little-endian float32 or
  float64, C order); the envelope's body is the header (name, point count, dtype,
  stamp, block). The client sends from its contiguous array and the server views the
  received frame (``copy=False``, ``np.frombuffer``): no per-point msgpack and no copy
  on the way (:class:`~reachwise.server.protocol.requests.ReplaceCloud`). The server
  indexes the cloud off its request thread and replies at once with the cloud's
  version.
- **The per-tick query** of a client that holds the scene's layout: one binary frame
  each way, joint states in, one float64 array of per-pair results (and the cloud
  table) out (:mod:`~reachwise.server.protocol.tick`,
  :class:`~reachwise.server.protocol.layout.Layout`).

The operations follow the phases of P-V Table 1: the *initialization phase* registers
robots (their YAML mapping, :func:`reachwise.io.robot_file.robot_to_dict`; never a
pickle) and part clouds, whose spatial indices the server builds once
(``add_robot``, ``add_object``, the ``watch*`` pair rules); ``replace_cloud`` hands over
new clouds at any rate; the *calculation phase* takes the inputs "object poses" — joint
states the server turns into link poses by forward kinematics, or run-time object poses
(``set_joints``, ``set_pose``) — and answers every watched pair (``query``), saying which
version of each cloud it used and when that cloud was measured.

Rules every decoder here follows (the server and the client alike):

- the message's size is checked *before* decoding (:attr:`Limits.max_message_bytes`),
  and msgpack itself is given length limits, so a hostile frame cannot make it allocate;
  lists and maps may nest at most :data:`MAX_DEPTH` levels (checked without recursion
  right after decoding), and an error message never formats a received value whole
  (:func:`safe_repr`);
- numpy arrays inside msgpack travel as ``[dtype, shape, bytes]`` (little-endian
  ``"<f8"`` floats, ``"<i8"`` integers, ``"|b1"`` booleans); the byte count must match
  the shape, and the row count of a cloud is checked against
  :attr:`Limits.max_cloud_points` before any array is made; a data frame must hold
  exactly the bytes its header announces;
- every field is checked for presence, type, shape and finiteness; unknown fields are
  errors; nothing is ever unpickled or evaluated. (The points of a streamed cloud are
  checked for finiteness by the indexing worker: a cloud with bad points is never
  swapped in, and ``block`` reports the error.)

A bad message becomes a :class:`ProtocolError` with an :class:`ErrorCode` and the name
of the offending field, which the server sends back as a typed error reply.

Units are SI: lengths in metres, angles in radians, times in seconds.

**Time stamps.** Every stamp on the wire is a reading of the clock of the client that
sent the input — joint states, run-time poses, the query itself and every cloud — and
the server never converts one: it hands each back as it got it (``measured_at``, the
oldest input an answer depends on; the cloud table's stamp of each cloud the answer
used). So a result's stamps are on the clock of the clients that fed the scene: by
default :func:`time.monotonic`, which every process on one host shares (a depth
camera process and a control process on the robot's computer agree without any
setup). Clients on several hosts, or a simulation with its own time, pass the same
clock to every client (``SceneClient(clock=...)``: a synchronized wall clock, the
simulated time); the server's own clock (:func:`time.monotonic` on its host) only
stamps an input that arrives without a stamp, which the
:class:`~reachwise.server.client.SceneClient` never sends. A cloud added with
``add_object`` does not age: its stamp is +inf, as in the in-process scene.

The package: :mod:`~reachwise.server.protocol.fields` (limits, error codes, the field
checks), :mod:`~reachwise.server.protocol.requests`,
:mod:`~reachwise.server.protocol.replies`, :mod:`~reachwise.server.protocol.codec`
(frames, and the fast path of the per-tick msgpack messages),
:mod:`~reachwise.server.protocol.layout`, :mod:`~reachwise.server.protocol.tick` and
:mod:`~reachwise.server.protocol.typed` (the messages of registered scene operations,
derived from their type hints);
everything public is here.
"""

from __future__ import annotations

from reachwise.server.protocol.codec import (
    DecodedReply,
    decode_frames,
    decode_reply,
    decode_request,
    encode_error,
    encode_frames,
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
    MAX_DEPTH,
    MAX_MESSAGE_BYTES,
    PROTOCOL_VERSION,
    SUPPORTED_VERSIONS,
    Buffer,
    ErrorCode,
    Limits,
    ProtocolError,
    Reader,
    check_array,
    check_depth,
    check_name,
    encode_array,
    failure_text,
    safe_repr,
    unchecked,
)
from reachwise.server.protocol.layout import Layout, layout_key
from reachwise.server.protocol.replies import (
    CLOUD_COLUMNS,
    REPLIES,
    ROW_COLUMNS,
    Ack,
    ErrorReply,
    HealthReply,
    HelloReply,
    MetricsReply,
    ObjectReply,
    OperationResult,
    PairInfo,
    QueryReply,
    Reply,
)
from reachwise.server.protocol.requests import (
    CLOUD_DTYPES,
    REQUESTS,
    AddObject,
    Health,
    Hello,
    Metrics,
    OperationCall,
    Query,
    ReplaceCloud,
    Request,
    SetJoints,
    SetPose,
)
from reachwise.server.protocol.tick import (
    TICK_MAGIC,
    TICK_REPLY_MAGIC,
    decode_tick,
    decode_tick_reply,
    encode_tick,
    encode_tick_inputs,
    encode_tick_reply,
    is_tick,
    is_tick_reply,
    read_tick,
    read_tick_reply,
    tick_query_reply,
    tick_reply_frame,
)
from reachwise.server.protocol.typed import decode_value, encode_value, operation

__all__ = [
    "BOOL",
    "CLOUD_COLUMNS",
    "CLOUD_DTYPES",
    "DEFAULT_LIMITS",
    "FLOAT",
    "INPUT_CODES",
    "INT",
    "MAX_CLOUD_POINTS",
    "MAX_DEPTH",
    "MAX_MESSAGE_BYTES",
    "PROTOCOL_VERSION",
    "REPLIES",
    "REQUESTS",
    "ROW_COLUMNS",
    "SUPPORTED_VERSIONS",
    "TICK_MAGIC",
    "TICK_REPLY_MAGIC",
    "Ack",
    "AddObject",
    "Buffer",
    "DecodedReply",
    "ErrorCode",
    "ErrorReply",
    "Health",
    "HealthReply",
    "Hello",
    "HelloReply",
    "Layout",
    "Limits",
    "Metrics",
    "MetricsReply",
    "ObjectReply",
    "OperationCall",
    "OperationResult",
    "PairInfo",
    "ProtocolError",
    "Query",
    "QueryReply",
    "Reader",
    "ReplaceCloud",
    "Reply",
    "Request",
    "SetJoints",
    "SetPose",
    "check_array",
    "check_depth",
    "check_name",
    "decode_frames",
    "decode_reply",
    "decode_request",
    "decode_tick",
    "decode_tick_reply",
    "decode_value",
    "encode_array",
    "encode_error",
    "encode_frames",
    "encode_reply",
    "encode_request",
    "encode_tick",
    "encode_tick_inputs",
    "encode_tick_reply",
    "encode_value",
    "failure_text",
    "is_tick",
    "is_tick_reply",
    "layout_key",
    "operation",
    "read_tick",
    "read_tick_reply",
    "safe_repr",
    "tick_query_reply",
    "tick_reply_frame",
    "unchecked",
]
