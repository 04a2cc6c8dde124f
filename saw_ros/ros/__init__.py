"""The ROS layer: the only code that imports rclpy and message packages."""
