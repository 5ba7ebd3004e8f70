"""The ROS layer of every node and tool: topics and packed messages (protocol), message checks, node and CLI helpers."""
