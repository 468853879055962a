from _types import cls

PtCtBlock = cls("phid_msgs/msg/PtCtBlock")
EncoderBlock = cls("phid_msgs/msg/EncoderBlock")
PmuBlock = cls("phid_msgs/msg/PmuBlock")
ExcitationBlock = cls("phid_msgs/msg/ExcitationBlock")
FieldControllerBlock = cls("phid_msgs/msg/FieldControllerBlock")
ScenarioMarker = cls("phid_msgs/msg/ScenarioMarker")
GeneratorParameters = cls("phid_msgs/msg/GeneratorParameters")
HamiltonianState = cls("phid_msgs/msg/HamiltonianState")
DisturbanceEvent = cls("phid_msgs/msg/DisturbanceEvent")
EventWindow = cls("phid_msgs/msg/EventWindow")
ControlParameters = cls("phid_msgs/msg/ControlParameters")
ModelValidation = cls("phid_msgs/msg/ModelValidation")
