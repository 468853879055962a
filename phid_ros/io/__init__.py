"""Input and output, by what is read or written.

- :mod:`phid_ros.io.bags`: rosbag2 folders and MCAP files, the message schemas;
- :mod:`phid_ros.io.field`: COMTRADE, PMU and trend-log exports through channel maps, test sheets;
- :mod:`phid_ros.io.csvset`: CSV scenario sets;
- :mod:`phid_ros.io.files`: outputs written whole or not at all, results JSON, digests, SQLite, YAML.

Beside them, what every reader produces: the recording (:mod:`~phid_ros.io.recording`), read in
parts (:mod:`~phid_ros.io.parts`) and summed up (:mod:`~phid_ros.io.overview`), on the sensor
topics (:mod:`~phid_ros.io.topics`).
"""
