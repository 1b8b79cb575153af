"""pilotlab's job kinds: one thin handler per module (record, frames, train, optimize, offline, online),
registered with `matrix.kinds.job_kind`."""
