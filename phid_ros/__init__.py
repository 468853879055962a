"""phid_ros: Port-Hamiltonian identification of synchronous generators from sensor streams."""

__version__ = "0.4.3"
