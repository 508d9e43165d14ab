"""One definition of the station names: topics, frames and labels from interface.py."""
import pytest

from drill_twin import interface as itf


@pytest.mark.parametrize('x_m', [700.0, 1590.0, 1250.5, 0.25])
def test_station_topic_round_trip(x_m):
    assert itf.station_from_topic(itf.vibration_displacement_topic(x_m)) == x_m
    assert itf.station_frame(x_m) == f'drill_twin/{itf.station_name(x_m)}'


def test_other_topics_are_not_stations():
    assert itf.station_from_topic(itf.vibration_imu_topic(700.0)) is None
    assert itf.station_from_topic(itf.BIT_STATE) is None
    assert itf.station_label(700.0) == '700 m'
