import time, rclpy
from rclpy.context import Context
ctx = Context(); rclpy.init(context=ctx)
node = rclpy.create_node('_ros2cli_direct_node', context=ctx, start_parameter_services=False)
end = time.monotonic() + 0.5
while time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.05)
print('\n'.join(sorted(t for t, _ in node.get_topic_names_and_types())))
