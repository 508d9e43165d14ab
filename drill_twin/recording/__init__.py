"""
Recording layer of drill_twin: rosbag2 bags of MCAP files.

None of its modules imports rclpy at import time: rclpy comes with ROS, and the functions
that serialise or deserialise a ROS message (writing a log, reading it decoded, a QoS
profile) import it when called, so that logs can be listed, read as CDR and recovered
without ROS. Modules:

- :mod:`~drill_twin.recording.message_types` - message classes from 'pkg/msg/Type' names;
- :mod:`~drill_twin.recording.schemas` - 'ros2msg' schema texts and type hashes as rosbag2
  writes them;
- :mod:`~drill_twin.recording.qos` - rosbag2's ``offered_qos_profiles`` YAML, rclpy QoS;
- :mod:`~drill_twin.recording.mcap_log` - :class:`McapLog`, the writer of one MCAP file;
- :mod:`~drill_twin.recording.bag` - the bag directory and its ``metadata.yaml``;
- :mod:`~drill_twin.recording.bag_writer` - :class:`BagWriter`, a bag split by log time;
- :mod:`~drill_twin.recording.log_metadata` - :class:`TwinLogMetadata`, the run description;
- :mod:`~drill_twin.recording.twin_log` - the twin node's log;
- :mod:`~drill_twin.recording.reader` - reading logs back (also cut ones);
- :mod:`~drill_twin.recording.recovery` - making a cut file whole;
- :mod:`~drill_twin.recording.resimulate` - re-running a logged twin and comparing.

Their rerun views are in :mod:`drill_twin.viz`.
"""

from drill_twin.recording.bag_writer import BagWriter
from drill_twin.recording.log_metadata import RECORD_NAME, TwinLogMetadata
from drill_twin.recording.mcap_log import McapLog
from drill_twin.recording.reader import iter_messages, LogMessage, read_metadata, topics

__all__ = ['BagWriter', 'iter_messages', 'LogMessage', 'McapLog', 'read_metadata', 'topics',
           'RECORD_NAME', 'TwinLogMetadata']
