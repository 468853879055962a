"""Online pipeline: ring buffer, alignment, detection, event store, recalibration, tracking.

Plain Python (no ROS): the ROS nodes and ``phid replay`` are thin front-ends over it.
"""
