"""The twin's engine (ROS-free): mean model + online ensemble, commands, events, KPIs."""
