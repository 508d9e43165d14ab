"""
The ROS 2 boundary of the twin: the rclpy node, its parameters, message conversion, replay.

Only this package (and the recorder's serialisation) imports rclpy and the message packages.
"""
