"""Message classes of the double: the rosbags typestore classes built from msg_schemas/."""

from phid_ros.io.msg_schemas import typestore


def cls(name: str):
    return typestore().types[name]
