"""Application services, by domain (no HTTP here: services raise the domain errors of
:mod:`.errors`; only ``app/core/errors.py`` knows status codes).

- :mod:`.run_lifecycle`: a run from upload to stored result (intake, accept, inversion,
  store, queue and jobs), reading stored runs, simulations;
- :mod:`.track`: what a track learns from its runs (alignment, aggregate, separation,
  register, quality, surveys, centerlines);
- :mod:`.vehicles`: vehicle versions, calibration, declared loads;
- :mod:`.views`: charts, exports, the report, notation;
- :mod:`.storage`: packed blocks, profiles, retention;
- :mod:`.lookup` (tracks and vehicles by id or name, made when new), :mod:`.context`,
  :mod:`.errors`, :mod:`.status`.
"""
