"""Load a study file, expand controller grids and enumerate its episodes (each with a key).

An *episode* is one (robot, generator, task index, controller, loop mode). Its key is the
SHA-256 of the JSON of everything that determines its numbers, so ``--resume`` recognises
stored episodes and a changed setting makes a new episode.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa

from otmm_qp import registry
from otmm_qp.config.base import PluginConfig
from otmm_qp.config.load import load, parse
from otmm_qp.config.schema import ControllerConfig
from otmm_qp.exceptions import ConfigError, OtmmError, PeerUnavailable
from otmm_qp.scenarios.generator import TaskGenerationError, task_seed
from otmm_qp.simulation.episode import step_count
from otmm_qp.studies.columns import descriptor_type
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.schema import GENERATOR_BUDGETS, StudyConfig, StudyController
from otmm_qp.studies.task import BuildCache, BuiltTask, PlannedEpisode, StudyTask, study_episode
from otmm_qp.studies.task_ids import check_entries, seed_name


def parse_study(data: Any, source: str = "study") -> StudyConfig:
    """Validate parsed YAML data (the one shaper of :func:`otmm_qp.config.load.parse`).

    Raises:
        ConfigError: Naming the first offending field and what is allowed.
    """
    return parse(StudyConfig, data, source)


def load_study(path: str | Path) -> StudyConfig:
    """Read a YAML study file with the hardened reader and validate it.

    Raises:
        ConfigError: Missing file, malformed or refused YAML (size, depth, aliases, duplicate
            keys, non-UTF-8) or invalid content (one line).
    """
    return load(StudyConfig, path, "study")


def _grid_size(spec: StudyController) -> int:
    """Controllers one study controller expands to: the product of its grid axis lengths."""
    size = 1
    for values in spec.grid.values():
        size *= len(values)
    return size


def check_plan_size(config: StudyConfig, source: str = "study") -> None:
    """Refuse a study larger than its stated ``limits`` before anything is allocated.

    Episodes counted: ``tasks × (controllers × loop modes + r)``, ``r = 1`` when
    ``reference.enabled`` (each task's offline reference is an episode too), else 0.

    Raises:
        ConfigError: Naming the bound, the study's size and how to raise the bound.
    """
    limits = config.limits
    hint = "raise limits.{} in the study file to run it"
    tasks = len(config.robots) * sum(g.count for g in config.generators)
    if tasks > limits.max_tasks:
        raise ConfigError(
            f"{source}: generators",
            f"{len(config.robots)} robots × {sum(g.count for g in config.generators):.3g} "
            f"tasks = {tasks:.3g} tasks exceeds limits.max_tasks = {limits.max_tasks}; "
            + hint.format("max_tasks"),
        )
    controllers = sum(_grid_size(c) for c in config.controllers)
    if controllers > limits.max_controllers:
        raise ConfigError(
            f"{source}: controllers",
            f"the grids expand to {controllers:.3g} controllers, more than "
            f"limits.max_controllers = {limits.max_controllers}; " + hint.format("max_controllers"),
        )
    references = 1 if config.reference.enabled else 0  # one reference episode per task
    episodes = tasks * (controllers * len(config.loop_modes) + references)
    if episodes > limits.max_episodes:
        per_task = f"{controllers} controllers × {len(config.loop_modes)} loop modes"
        if references:
            per_task = f"({per_task} + 1 reference)"
        raise ConfigError(
            f"{source}: controllers",
            f"{tasks} tasks × {per_task} = {episodes:.3g} episodes exceeds "
            f"limits.max_episodes = {limits.max_episodes}; " + hint.format("max_episodes"),
        )
    for j, gen in enumerate(config.generators):
        for name in GENERATOR_BUDGETS:
            value = gen.params.get(name)
            if isinstance(value, int | float) and value > limits.max_generator_budget:
                raise ConfigError(
                    f"{source}: generators.{j}.{name}",
                    f"{value:.3g} exceeds limits.max_generator_budget = "
                    f"{limits.max_generator_budget}; " + hint.format("max_generator_budget"),
                )


def _format_value(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _grid_target(spec: StudyController, key: str, field: str) -> tuple[str, int | None, str]:
    """Which block a grid key sets: ``("backend"|"filters", index, parameter)``."""
    parts = key.split(".")
    if parts[0] == "backend" and len(parts) == 2:
        return "backend", None, parts[1]
    if parts[0] == "filters" and len(parts) == 3 and parts[1].isdigit():
        index = int(parts[1])
        if index >= len(spec.filters):
            raise ConfigError(f"{field}.grid.{key}", f"controller has {len(spec.filters)} filters")
        return "filters", index, parts[2]
    if len(parts) != 1:
        raise ConfigError(f"{field}.grid.{key}", "use NAME, backend.NAME or filters.INDEX.NAME")
    owners: list[tuple[str, int | None]] = []
    blocks: list[tuple[str, int | None, PluginConfig, str]] = [
        ("filters", j, f, registry.FILTERS) for j, f in enumerate(spec.filters)
    ]
    blocks.append(("backend", None, spec.backend, registry.BACKENDS))
    for kind, position, block, group in blocks:
        try:
            registry.check_parameters(registry.load(group, block.type), {key: None}, "")
        except ConfigError:
            continue
        except OtmmError:
            continue
        owners.append((kind, position))
    if not owners:
        raise ConfigError(f"{field}.grid.{key}", "unknown parameter for every block")
    if len(owners) > 1:
        raise ConfigError(
            f"{field}.grid.{key}", "accepted by several blocks; use backend.NAME or filters.I.NAME"
        )
    return owners[0][0], owners[0][1], key


def expand_controllers(config: StudyConfig, source: str = "study") -> list[ControllerConfig]:
    """One :class:`ControllerConfig` per grid combination, named ``name[k=v,...]``.

    Raises:
        ConfigError: Empty grid axis, grid key no block accepts, or duplicate names.
    """
    from otmm_qp.runner.plant_stage import plant_record

    expanded: list[ControllerConfig] = []
    for i, spec in enumerate(config.controllers):
        field = f"{source}: controllers.{i}"
        for key, values in spec.grid.items():
            if not values:
                raise ConfigError(f"{field}.grid.{key}", "empty list: expands to zero controllers")
        targets = {key: _grid_target(spec, key, field) for key in spec.grid}
        keys = list(spec.grid)
        for combination in itertools.product(*(spec.grid[k] for k in keys)):
            filters = [dict(f.params, type=f.type) for f in spec.filters]
            backend = dict(spec.backend.params, type=spec.backend.type)
            for key, value in zip(keys, combination, strict=True):
                kind, index, name = targets[key]
                block = backend if kind == "backend" else filters[index or 0]
                block[name] = value
            label = spec.name
            if keys:
                label += (
                    "["
                    + ",".join(
                        f"{k.rsplit('.', 1)[-1]}={_format_value(v)}"
                        for k, v in zip(keys, combination, strict=True)
                    )
                    + "]"
                )
            conditioning = [dict(c.params, type=c.type) for c in spec.conditioning]
            for plant_name, plant in _plant_axis(config):
                record: dict[str, Any] = {"name": label, "filters": filters, "backend": backend}
                if conditioning:
                    record["conditioning"] = conditioning
                if plant_name is not None:  # the plants axis overrides a controller's own plant
                    record.update(name=f"{label}@{plant_name}", plant=plant)
                elif spec.plant is not None:
                    record["plant"] = plant_record(spec.plant)
                expanded.append(ControllerConfig.model_validate(record))
    names = [c.name for c in expanded]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ConfigError(
            f"{source}: controllers", f"grid expands to duplicate names: {', '.join(duplicates)}"
        )
    return expanded


def _plant_axis(config: StudyConfig) -> list[tuple[str | None, Any]]:
    """``(name, plant record)`` of each value of the ``plants`` axis; ``[(None, None)]`` if none."""
    from otmm_qp.runner.plant_stage import plant_record

    if config.plants is None:
        return [(None, None)]
    return [(p.name, plant_record(p.plant)) for p in config.plants]


def controller_record(config: ControllerConfig) -> dict[str, Any]:
    """JSON-ready record of a controller (name, filters, backend with parameters).

    ``conditioning`` and ``plant`` appear only when set, so the episode keys of a study
    without them are those it had before plants existed.
    """
    from otmm_qp.runner.plant_stage import plant_record

    record: dict[str, Any] = {
        "name": config.name,
        "filters": [dict(f.params, type=f.type) for f in config.filters],
        "backend": dict(config.backend.params, type=config.backend.type),
    }
    if config.conditioning:
        record["conditioning"] = [dict(s.params, type=s.type) for s in config.conditioning]
    if config.plant is not None:
        record["plant"] = plant_record(config.plant)
    return record


@dataclass
class StudyPlan:
    """A validated study ready to run.

    Attributes:
        config: The study record.
        controllers: Expanded controllers (available ones only).
        skipped: ``(name, reason)`` of controllers whose peer library is missing.
        episodes: Every episode in a fixed order (each task's reference, when enabled, before
            its controllers).
        task_columns: Arrow types of the ``task.*`` descriptor columns of the generators'
            first tasks (every part stores them, see :mod:`otmm_qp.studies.columns`).
    """

    config: StudyConfig
    controllers: list[ControllerConfig]
    skipped: list[tuple[str, str]]
    episodes: list[PlannedEpisode]
    task_columns: dict[str, pa.DataType] = dataclasses.field(default_factory=dict)

    def payload(self) -> dict[str, Any]:
        """JSON-ready description the workers rebuild everything from."""
        return {
            "config": self.config.model_dump(mode="json"),
            "controllers": [controller_record(c) for c in self.controllers],
        }


def _digest(record: Any) -> str:
    text = json.dumps(record, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def episode_key(
    config: StudyConfig,
    robot: int,
    generator: int,
    index: int,
    controller: dict[str, Any],
    loop_mode: str,
) -> str:
    """Hash of the episode's full spec (robot, task, controller, loop, numerics, metrics)."""
    robot_spec = config.robots[robot]
    gen = config.generators[generator]
    record = {
        "robot": robot_spec.model_dump(mode="json"),
        "generator": {"type": gen.type, "params": gen.params},
        "seed": task_seed(config.seed, robot_spec.name, seed_name(config, generator), index),
        "task_index": index,
        "controller": controller,
        "loop_mode": loop_mode,
        "dt": config.dt,
        "clik_gain": config.clik_gain,
        "duration": config.duration.model_dump(mode="json"),
        "metrics": config.metrics.model_dump(mode="json"),
    }
    return _digest(record)


def oracle_key(config: StudyConfig, robot: int, generator: int, index: int, seed: int) -> str:
    """Key of a task's reference episode: the task, the numerics and what it solves for."""
    gen = config.generators[generator]
    record = {
        "robot": config.robots[robot].model_dump(mode="json"),
        "generator": {"type": gen.type, "params": gen.params},
        "seed": seed,
        "task_index": index,
        "controller": REFERENCE_NAME,
        "dt": config.dt,
        "duration": config.duration.model_dump(mode="json"),
        "metrics": config.metrics.model_dump(mode="json"),
        "success": config.success.model_dump(mode="json"),
        "reference": config.reference.model_dump(mode="json"),
    }
    return _digest(record)


def check_plugins(
    config: StudyConfig, controllers: list[ControllerConfig], source: str
) -> tuple[list[tuple[str, str]], dict[str, Any]]:
    """Build every robot, generator and controller once so bad input fails before any work.

    Each robot is built once; each generator draws its first task on each robot (a generator
    that cannot work on a robot fails here), and every controller is prepared like a run's
    (:func:`~otmm_qp.runner.prepare.prepare`: one dry-run step on a copy) on the robot's first
    task, whose episode also meets the step cap.

    Returns:
        ``(name, reason)`` of controllers skipped because their peer library is missing, and
        the ``task.*`` descriptors of the first tasks (their names and example values).

    Raises:
        ConfigError: Unknown plugin or parameter, a controller that does not fit a robot, or
            an episode (or its plant steps, ``steps × substeps`` of the longest first
            task) over ``max_steps``, with its path.
    """
    from otmm_qp.runner.build import build_controller, load_robot
    from otmm_qp.runner.prepare import prepare

    robots = [
        load_robot(spec.robot, f"{source}: robots.{i}.robot")
        for i, spec in enumerate(config.robots)
    ]
    generators = [
        registry.create(registry.TASK_GENERATORS, gen.type, gen.params, f"{source}: generators.{j}")
        for j, gen in enumerate(config.generators)
    ]
    cache = BuildCache()  # the tasks are built from these robots and generators
    for i, robot in enumerate(robots):
        cache.robots[BuildCache.robot_key(config, i)] = robot
    for j, generator in enumerate(generators):
        cache.generators[BuildCache.generator_key(config, j)] = generator
    built, skipped = [], []
    descriptors: dict[str, Any] = {}
    for k, controller in enumerate(controllers):
        try:
            built.append(
                build_controller(
                    controller,
                    f"{source}: controllers.{k} ({controller.name})",
                    config.metrics.blow_up_speed,
                )
            )
        except PeerUnavailable as error:
            skipped.append((controller.name, str(error)))
    for i, (spec, robot) in enumerate(zip(config.robots, robots, strict=True)):
        if spec.task_weight is not None and len(spec.task_weight) != robot.task_dim:
            raise ConfigError(
                f"{source}: robots.{i}.task_weight",
                f"expected {robot.task_dim} weights, got {len(spec.task_weight)}",
            )
        tasks = [_first_task(config, i, j, cache, source) for j in range(len(generators))]
        for made in tasks:
            descriptors.update({f"task.{k}": v for k, v in made.task.descriptors.items()})
        field = f"{source}: robots.{i} ({spec.name}) first task of generators.0"
        try:
            episode = study_episode(config, tasks[0], config.loop_modes[0])
        except ConfigError as error:
            where = "duration" if error.field == "duration" else error.field
            raise ConfigError(f"{field}: {where}", error.message) from None
        except OtmmError as error:
            raise ConfigError(field, str(error)) from None
        prepare(
            episode, built, f"{source}: robots.{i}", reachable=False,
            declarations=_declarations(config, controllers),
        )  # fmt: skip
        longest = max(step_count(made.duration, config.dt) for made in tasks)
        _check_stages(config, controllers, robot, episode.q0, (longest, config.max_steps), source)
    return skipped, descriptors


def _declarations(config: StudyConfig, controllers: list[ControllerConfig]) -> dict[str, list[Any]]:
    """What the plants each controller runs under declare (the ``plants`` axis, else its own)."""
    from otmm_qp.runner.plant_stage import plant_declarations, plant_record

    if config.plants is not None:
        axis = plant_declarations([plant_record(p.plant) for p in config.plants], config.dt)
        return {c.name: axis for c in controllers}
    return {c.name: plant_declarations([plant_record(c.plant)], config.dt) for c in controllers}


def _check_stages(
    config: StudyConfig, controllers: list[ControllerConfig], robot: Any, q0: Any,
    budget: tuple[int, int], source: str,
) -> None:  # fmt: skip
    """Build and reset every plant and every conditioning on ``robot`` at ``q0``.

    The plants are those of the ``plants`` axis, else the controllers' own; each is checked
    like a run's (:func:`~otmm_qp.runner.plant_stage.check_plant`), ``steps × substeps``
    against ``max_steps`` included.

    Args:
        config: The study.
        controllers: The expanded controllers.
        robot: The arm.
        q0: Start configuration of its first task (nq,).
        budget: ``(steps, max_steps)``: the control steps of the robot's longest first-task
            episode (one per generator) and the study's cap.
        source: Config path prefix of the errors.

    Raises:
        ConfigError: Naming ``plants.I.plant``, the controller's ``plant`` or its
            ``conditioning``.
    """
    from otmm_qp.runner.plant_stage import check_conditioning, check_plant, plant_record

    for j, plant in enumerate(config.plants or []):
        field = f"{source}: plants.{j}.plant"
        check_plant(plant_record(plant.plant), robot, q0, config.dt, field, budget)
    if config.plants is None:  # the axis replaces the controllers' own plants
        checked: set[str] = set()
        for k, controller in enumerate(controllers):
            record = plant_record(controller.plant)
            if record is not None and repr(record) not in checked:
                checked.add(repr(record))
                field = f"{source}: controllers.{k} ({controller.name}).plant"
                check_plant(record, robot, q0, config.dt, field, budget)
    conditioning = {
        c.name: [dict(s.params, type=s.type) for s in c.conditioning]
        for c in controllers
        if c.conditioning
    }
    check_conditioning(conditioning, robot, config.dt, source)


def _first_task(
    config: StudyConfig, robot: int, index: int, cache: BuildCache, source: str
) -> BuiltTask:
    """Entry ``index``'s first task on ``robot``; a generator that cannot work on it is refused."""
    gen = config.generators[index]
    seed = task_seed(config.seed, config.robots[robot].name, seed_name(config, index), 0)
    try:
        return StudyTask(robot, index, 0, seed).build(config, cache)
    except TaskGenerationError as error:
        raise ConfigError(f"{source}: generators.{index} ({gen.type})", str(error)) from None


def plan_study(config: StudyConfig, source: str = "study") -> StudyPlan:
    """Expand, check and enumerate a study.

    Raises:
        ConfigError: Any bad input, one line naming the field.
    """
    check_plan_size(config, source)
    check_entries(config, source)
    controllers = expand_controllers(config, source)
    skipped, descriptors = check_plugins(config, controllers, source)
    skipped_names = {name for name, _ in skipped}
    controllers = [c for c in controllers if c.name not in skipped_names]
    if not controllers:
        raise ConfigError(f"{source}: controllers", "no controller is available to run")
    records = [controller_record(c) for c in controllers]
    episodes: list[PlannedEpisode] = []
    for r, robot in enumerate(config.robots):
        for g, gen in enumerate(config.generators):
            for index in range(gen.count):
                seed = task_seed(config.seed, robot.name, seed_name(config, g), index)
                task = StudyTask(r, g, index, seed)
                if config.reference.enabled:  # once per task, before its controllers
                    key = oracle_key(config, r, g, index, seed)
                    episodes.append(PlannedEpisode.reference(key, task))
                for c, record in enumerate(records):
                    for mode in config.loop_modes:
                        key = episode_key(config, r, g, index, record, mode)
                        episodes.append(PlannedEpisode.of_controller(key, task, c, mode))
    task_columns = {name: descriptor_type([value]) for name, value in descriptors.items()}
    return StudyPlan(config, controllers, skipped, episodes, task_columns)
