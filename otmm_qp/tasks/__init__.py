"""Task generators: reproducible random tasks (start configuration + trajectory) for studies."""

from otmm_qp.tasks.generator import Task, TaskGenerator, task_seed

__all__ = ["Task", "TaskGenerator", "task_seed"]
