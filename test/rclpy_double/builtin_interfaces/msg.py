from _types import cls

Time = cls("builtin_interfaces/msg/Time")
