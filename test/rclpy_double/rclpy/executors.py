class ExternalShutdownException(Exception):
    """Test double of rclpy.executors.ExternalShutdownException."""
