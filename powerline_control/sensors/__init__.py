"""Sensor placement: select_sensors with its criteria, convex relaxation and certificate, integer
searches and baselines, and the sensor-count study (how many sensors a model needs).

Modules: select (the public entry), criteria, constraints, relaxation, search, baselines, count,
results. ``powerline_control.sensors`` keeps every name the single module ``sensors.py`` had.
"""

from .count import sensor_count_study
from .results import Baseline, SensorCountStudy, SensorSelection
from .select import select_sensors

__all__ = ["select_sensors", "SensorSelection", "Baseline", "sensor_count_study",
           "SensorCountStudy"]
