"""pilotlab's job kinds: one thin handler per kind (record, train, optimize, offline, online, report)."""
