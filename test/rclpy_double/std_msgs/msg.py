from _types import cls

Header = cls("std_msgs/msg/Header")
