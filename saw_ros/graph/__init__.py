"""The graph layer: starts and stops our nodes as processes (no rclpy import)."""
