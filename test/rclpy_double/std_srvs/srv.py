"""Test double of std_srvs.srv.Trigger."""

from dataclasses import dataclass


class Trigger:
    @dataclass
    class Request:
        pass

    @dataclass
    class Response:
        success: bool = False
        message: str = ""
