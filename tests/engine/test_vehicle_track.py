"""Vehicle and track parameters: defaults, validation, derived quantities."""

import math

import numpy as np
import pytest

from engine.errors import ParameterError
from engine.track import SoftZone, Track, TrackParams
from engine.vehicle import TABLE1, VehicleParams


def test_table1_defaults_and_static_loads():
    """Table 1 vehicle: rear axle 1100 kg, static loads share the body by the axle distances."""
    assert TABLE1.mu2 == 1100.0 and TABLE1.mu1 == 700.0
    p1, p2 = TABLE1.static_axle_loads()
    assert p1 == pytest.approx((8100 + 700) * 9.81)
    assert p2 == pytest.approx((8100 + 1100) * 9.81)


@pytest.mark.parametrize(
    "field,value", [("ms", -1.0), ("kt1", 0.0), ("d1", float("nan")), ("cs1", -5.0)]
)
def test_vehicle_rejects_bad_values_with_named_parameter(field, value):
    """A negative mass or zero stiffness is an error naming the parameter, not a NaN later."""
    with pytest.raises(ParameterError, match=field):
        VehicleParams(**{field: value})


def test_vehicle_from_dict_rejects_unknown_keys():
    """Unknown parameter names are reported, missing ones take Table 1 values."""
    assert VehicleParams.from_dict({"ms": 20000}).ms == 20000.0
    with pytest.raises(ParameterError, match="mass"):
        VehicleParams.from_dict({"mass": 1})


def test_vehicle_matrices_symmetric_positive_definite():
    """M, C, K are symmetric; K is positive definite with the contact springs."""
    M, C, K = TABLE1.matrices()
    for A in (M, C, K):
        assert np.allclose(A, A.T)
    assert np.all(np.linalg.eigvalsh(K) > 0)


def test_soft_zone_parse_and_supports():
    """'start:end:loss' softens the supports within [start, end] (inclusive)."""
    z = SoftZone.parse("80:84:0.4")
    t = Track(150.0, zones=[z])
    soft = t.support_x[t.k < t.params.k_nominal]
    assert soft[0] == pytest.approx(80.4) and soft[-1] == pytest.approx(84.0)
    assert np.allclose(t.k[t.k < 8e7], 0.6 * 8e7)
    assert t.n_supports == 251


@pytest.mark.parametrize("text", ["80:84", "a:b:c", "84:80:0.4", "80:84:1.2"])
def test_soft_zone_parse_errors(text):
    """Malformed zones are rejected with a message."""
    with pytest.raises(ParameterError):
        SoftZone.parse(text)


def test_track_support_array_validated():
    """An explicit stiffness array must have one positive value per support."""
    with pytest.raises(ParameterError, match="one value per support"):
        Track(10.0, support_stiffness=np.ones(3))
    with pytest.raises(ParameterError, match="support_stiffness"):
        Track(3.0, support_stiffness=np.array([1.0, -1.0, 1.0, 1.0, 1.0, 1.0]))


def test_winkler_closed_form_value():
    """The front axle's Winkler deflection is about 0.49 mm (model.md)."""
    p1, _ = TABLE1.static_axle_loads()
    assert TrackParams().winkler_deflection(p1) == pytest.approx(0.489e-3, rel=0.01)
    # a 50 % loss raises it by 0.5**-0.75
    ratio = TrackParams().winkler_deflection(p1, 0.5) / TrackParams().winkler_deflection(p1)
    assert ratio == pytest.approx(0.5**-0.75)
    assert math.isclose(TrackParams().EI, 210e9 * 3.055e-5)
