"""The domain layer: the benchmark's scenario concepts, between core and the experiments of study. Scenarios and
their files, the sweep families and their perturbed plants, the job and its execution through the one closed loop,
the clairvoyant floor of a job, and a comparison's result. envs and media build on this layer and core alone; study,
rl and the command above it. Every name below loads on first use."""

from __future__ import annotations

from typing import TYPE_CHECKING

from mjtraj._lazy import lazy_exports

_EXPORTS = {
    "Scenario": "mjtraj.domain.scenario",
    "load_scenario": "mjtraj.domain.scenario",
    "scenario_text": "mjtraj.domain.scenario",
    "scenario_for_model": "mjtraj.domain.scenario",
    "scenario_from_dict": "mjtraj.domain.scenario",
    "default_scenario_path": "mjtraj.domain.scenario",
    "FAMILIES": "mjtraj.domain.families",
    "FAMILY_ID": "mjtraj.domain.families",
    "FamilyScenario": "mjtraj.domain.families",
    "PAYLOAD_MASS": "mjtraj.domain.families",
    "Perturbation": "mjtraj.domain.families",
    "draw_scenario": "mjtraj.domain.families",
    "draw_family": "mjtraj.domain.families",
    "arm_scales": "mjtraj.domain.families",
    "perturbed_plant": "mjtraj.domain.families",
    "plant_fields": "mjtraj.domain.families",
    "measurement_noise": "mjtraj.domain.families",
    "draw_perturbation": "mjtraj.domain.families",
    "no_perturbation": "mjtraj.domain.families",
    "noise_scale": "mjtraj.domain.families",
    "ORACLE_LABEL": "mjtraj.domain.oracle",
    "TrueParameters": "mjtraj.domain.oracle",
    "true_parameters": "mjtraj.domain.oracle",
    "Actor": "mjtraj.domain.pipeline",
    "Job": "mjtraj.domain.pipeline",
    "Outcome": "mjtraj.domain.pipeline",
    "execute": "mjtraj.domain.pipeline",
    "execute_batch": "mjtraj.domain.pipeline",
    "plan_failure": "mjtraj.domain.pipeline",
    "one_line": "mjtraj.domain.pipeline",
    "goal_checked": "mjtraj.domain.pipeline",
    "STATUSES": "mjtraj.domain.pipeline",
    "Floor": "mjtraj.domain.floor",
    "floor_of": "mjtraj.domain.floor",
    "floors_of": "mjtraj.domain.floor",
    "Comparison": "mjtraj.domain.comparison",
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:
    from mjtraj.domain.comparison import Comparison
    from mjtraj.domain.families import (
        FAMILIES,
        FAMILY_ID,
        PAYLOAD_MASS,
        FamilyScenario,
        Perturbation,
        arm_scales,
        draw_family,
        draw_perturbation,
        draw_scenario,
        measurement_noise,
        no_perturbation,
        noise_scale,
        perturbed_plant,
        plant_fields,
    )
    from mjtraj.domain.floor import Floor, floor_of, floors_of
    from mjtraj.domain.oracle import ORACLE_LABEL, TrueParameters, true_parameters
    from mjtraj.domain.pipeline import (
        STATUSES,
        Actor,
        Job,
        Outcome,
        execute,
        execute_batch,
        goal_checked,
        one_line,
        plan_failure,
    )
    from mjtraj.domain.scenario import (
        Scenario,
        default_scenario_path,
        load_scenario,
        scenario_for_model,
        scenario_from_dict,
        scenario_text,
    )

__all__ = [
    "Actor", "Comparison", "FAMILIES", "FAMILY_ID", "FamilyScenario", "Floor", "Job", "ORACLE_LABEL", "Outcome",
    "PAYLOAD_MASS", "Perturbation", "STATUSES", "Scenario", "TrueParameters", "arm_scales", "default_scenario_path",
    "draw_family", "draw_perturbation", "draw_scenario", "execute", "execute_batch", "floor_of", "floors_of",
    "goal_checked", "load_scenario", "measurement_noise", "no_perturbation", "noise_scale", "one_line",
    "perturbed_plant", "plan_failure", "plant_fields", "scenario_for_model", "scenario_from_dict", "scenario_text",
    "true_parameters",
]
