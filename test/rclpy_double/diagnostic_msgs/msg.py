from _types import cls

DiagnosticArray = cls("diagnostic_msgs/msg/DiagnosticArray")
DiagnosticStatus = cls("diagnostic_msgs/msg/DiagnosticStatus")
KeyValue = cls("diagnostic_msgs/msg/KeyValue")
