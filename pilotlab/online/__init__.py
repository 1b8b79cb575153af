"""Closed-loop evaluation: brains drive the simulator's car, and BehaviorMetrics' metrics are
computed from what happened (see `pilotlab.online.metrics` for the definitions)."""
