"""
The ROS 2 boundary of the twin: the rclpy node, its parameters, message conversion, replay.

``twin_node`` wires the node (publishers, subscriptions, timers) and calls into one module a
concept: ``clock`` (pace and epoch, on ``pacing``), ``commands``, ``measurements``,
``outputs`` (publishing gated by subscribers), ``run_log`` (the MCAP log and its failures),
``diagnostics`` (health), ``watchers`` (live view, console), ``node_parameters`` (the ROS
side of ``parameters``); ``messages`` converts snapshots to messages; ``build`` makes the
engine and the log outside the node; ``replay`` republishes a log.
Only this package (and the recorder's serialisation) imports rclpy and the message packages.
"""
