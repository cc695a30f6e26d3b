"""A run's lifecycle, from upload to stored result, in the manner of Netflix dispatch.

- :mod:`.intake`: the upload parsed into a :class:`~.intake.Submission`; the track and vehicle
  it names;
- :mod:`.accept`: :func:`~.accept.submit`: check everything, then one transaction (processed
  now when short, else queued);
- :mod:`.inversion`: the engine's inversion of a run's log, in the request or the worker;
- :mod:`.store`: a run's rows, and :func:`~.store.complete_run`, the one way a finished
  inversion is stored (inline and queued alike);
- :mod:`.lease` and :mod:`.queue`: claims, heartbeats, recovery; the worker's threads;
- :mod:`.jobs`: each kind of the worker's work, looked up in :data:`~.jobs.JOBS`;
- :mod:`.processing` (the engine called, its result stored), :mod:`.handover` (prepared runs
  handed to this process's worker), :mod:`.logs` and :mod:`.json_log` (reading uploads),
  :mod:`.stored_runs` (reading stored runs), :mod:`.simulation` (synthetic runs).
"""
