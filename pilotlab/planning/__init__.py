"""Planning: a validated recipe -> the job DAG (pilotlab.planning.planner), its laps
(pilotlab.planning.laps) and its BehaviorMetrics worlds (pilotlab.planning.worlds)."""
from pilotlab.planning.planner import Planner, plan

__all__ = ["Planner", "plan"]
