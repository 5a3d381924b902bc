"""Bag I/O: every kind of bag the tools read and write (ROS 1 ``.bag``, rosbag2 folders with sqlite3 or mcap storage,
single ``.mcap`` / ``.db3`` files), through the PyPI ``rosbags`` library.

- :mod:`.reader`: :func:`~.reader.open_bag` and the same reading interface for every kind; topics, camera_info
  pairing and the depth frames of a bag.
- :mod:`.writer`: :class:`~.writer.BagWriter`, a new bag in any kind (messages converted between ROS versions).
- :mod:`.messages`: the message definitions (one typestore) and the helpers that read and build messages of either
  ROS version; the depth image and camera conversions are the C++ core's, the ones the ROS node uses.
- :mod:`.tf`: the bag's /tf and /tf_static, looked up at a stamp.
- :mod:`.ros1`: ROS 1 bags read record by record, so that a damaged record is named (topic, byte offset).
"""
