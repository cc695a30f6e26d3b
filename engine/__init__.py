"""Drive-by track monitoring engine: pure numerics (numpy/scipy), no web or database imports.

From car-body IMU logs (vertical acceleration, pitch rate) to the loaded track profile under
each wheel, mapped to chainage, with soft spots and stiffness-loss estimates.

Quick start::

    from engine import RunSetup, prepare_run, process_run, read_run_csv
    log = read_run_csv("run.csv")
    result = process_run(prepare_run(log, RunSetup(start_chainage_m=24.13)))
    for spot in result.soft_spots:
        print(spot.start_m, spot.end_m, spot.depth_mm, spot.stiffness_loss_pct)

Units are SI inside (m, s, N, kg, rad); levels are returned in mm, positive up.
"""

from .aggregate import AggregateProfile, aggregate_levels
from .align import Alignment, align_profiles
from .detect import DetectionConfig
from .direct import DirectResult, direct_inverse, direct_inverse_loop, filtered_direct_inverse
from .errors import EngineError, InversionError, LogFormatError, ParameterError
from .logio import CsvOptions, preview_csv, read_run_csv, write_run_csv
from .pipeline import METHODS, process_run
from .register import Defect, Limits, Observation, RegisterConfig, RunCoverage, build_register
from .results import ProcessResult, Quality, SoftSpot
from .runlog import RunLog
from .sensor import SensorModel
from .setup import PreparedRun, ProcessConfig, RunSetup, prepare_run
from .simulate import SimulationResult, simulate
from .track import SoftZone, Track, TrackParams
from .vehicle import GRAVITY, TABLE1, VehicleParams

__all__ = [
    "GRAVITY", "METHODS", "TABLE1", "AggregateProfile", "Alignment", "CsvOptions", "Defect",
    "DetectionConfig", "DirectResult", "EngineError", "InversionError", "Limits",
    "LogFormatError", "Observation", "ParameterError", "PreparedRun", "ProcessConfig",
    "ProcessResult", "Quality", "RegisterConfig", "RunCoverage", "RunLog", "RunSetup",
    "SensorModel", "SimulationResult", "SoftSpot", "SoftZone", "Track", "TrackParams",
    "VehicleParams", "aggregate_levels", "align_profiles", "build_register", "direct_inverse",
    "direct_inverse_loop", "filtered_direct_inverse", "prepare_run", "preview_csv",
    "process_run", "read_run_csv", "simulate", "write_run_csv",
]  # fmt: skip
