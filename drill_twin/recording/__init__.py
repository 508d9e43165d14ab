"""Recording layer of drill_twin: rosbag2-compatible MCAP logs and their rerun views.

Modules (none imports rclpy or rerun at import time):

- :mod:`~drill_twin.recording.message_types` - message classes from 'pkg/msg/Type' names;
- :mod:`~drill_twin.recording.schemas` - 'ros2msg' schema texts and type hashes as rosbag2
  writes them;
- :mod:`~drill_twin.recording.qos` - rosbag2's ``offered_qos_profiles`` YAML, rclpy QoS;
- :mod:`~drill_twin.recording.mcap_log` - :class:`McapLog`, the writer;
- :mod:`~drill_twin.recording.reader` - reading logs back (also truncated ones);
- :mod:`~drill_twin.recording.rerun_view` - rerun blueprint, ``.rrd`` conversion, viewer.
"""

from drill_twin.recording.mcap_log import McapLog, TWIN_METADATA_NAME
from drill_twin.recording.reader import iter_messages, LogMessage, read_metadata, topics

__all__ = ['iter_messages', 'LogMessage', 'McapLog', 'read_metadata', 'topics',
           'TWIN_METADATA_NAME']
