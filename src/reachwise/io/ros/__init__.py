"""ROS 1 and ROS 2 recordings without ROS: messages to arrays, bags in and out.

The decoding layer is pure: each function takes a deserialized message (any object with
the message's fields, as :mod:`rosbags` makes them) and returns numpy arrays, or raises
:class:`~reachwise.io.ros.recording_error.RecordingError` naming the topic, the time and
the field at fault.

- :mod:`~reachwise.io.ros.pointcloud2` — ``sensor_msgs/PointCloud2`` to points;
- :mod:`~reachwise.io.ros.depth_image` — ``sensor_msgs/Image`` depth (``16UC1``,
  ``32FC1``) and ``sensor_msgs/CameraInfo`` to points in the optical frame;
- :mod:`~reachwise.io.ros.transform_tree` — ``/tf`` and ``/tf_static`` to 4 × 4
  transforms, interpolated in time, looked up along the tree;
- :mod:`~reachwise.io.ros.joint_state` — ``sensor_msgs/JointState`` to a robot's ``q``,
  by joint name;
- :mod:`~reachwise.io.ros.bag` reads a recording (ROS 1 ``.bag``, ROS 2 sqlite3 or MCAP)
  and :mod:`~reachwise.io.ros.bag_writer` writes one (ROS 2 sqlite3 or MCAP);
  :mod:`~reachwise.io.ros.messages` builds the messages it writes.

Reading and writing bags needs the optional package ``rosbags`` (the ``ros`` extra);
the decoding functions need nothing beyond numpy and scipy.
"""
