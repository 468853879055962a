"""Input/output: message schemas, bags (rosbag2 + MCAP), CSV import, JSON results."""
