"""Plant simulator: network, generator plant, sensors, scenario catalogue."""
