"""The ROS layer every node and tool shares: topics and packed messages (protocol), message checks, node and CLI helpers."""
