"""Study scenarios — "tasks" in study files and results: a start configuration and a trajectory.

Reproducible random generators (entry-point group ``otmm_qp.task_generators``), the model's true
reach, and the singular-configuration search they use.
"""

from otmm_qp.scenarios.generator import Task, TaskGenerator, task_seed

__all__ = ["Task", "TaskGenerator", "task_seed"]
