"""`mjtraj rl`: train tracking policies, score any policy by the benchmark protocol, and manage the shipped
baselines (one handler per subcommand)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from mjtraj.cli.common import (
    Parser,
    Progress,
    command_line,
    figure_format_option,
    names,
    no_progress_option,
    overrides,
    widths,
)
from mjtraj.rl.protocol import PROTOCOL, PROTOCOL_V2, PROTOCOLS


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj rl` and its subcommands; a bare `mjtraj rl` lists them."""
    rl = sub.add_parser("rl", help="RL tracking policies: train on the UR5Track-v1 envs (the rl extra), score any "
                        "policy by the benchmark protocol beside the planners and control laws")
    rl.set_defaults(handler=lambda args: _list(rl))
    rl_sub = rl.add_subparsers(dest="rl_command", parser_class=Parser)
    p = rl_sub.add_parser("train", help="train an SB3 agent on the vectorised env; checkpoints, learning curve, "
                          "run.json")
    p.add_argument("--algo", default="sac", help="sac | ppo | td3 | recurrent_ppo (sb3-contrib's LSTM PPO: "
                   "memory across an episode) (default sac)")
    p.add_argument("--action-mode", dest="action_mode", default="residual",
                   help="residual (added to feedforward + PID) | torque (the whole corrective torque); default "
                   "residual")
    p.add_argument("--residual-scale", dest="residual_scale", type=float,
                   help="N m per unit of action in residual mode (default 6: PID's median per-joint RMS feedback "
                   "torque on the mismatch family)")
    p.add_argument("--observe-control", dest="observe_control", action="store_true",
                   help="the policy also observes the PID integral and the next feedforward torque")
    p.add_argument("--observe-plant", dest="observe_plant", default="none",
                   help="none | true: the policy also observes the plant's payload, damping and friction (a "
                   "privileged teacher, labelled so in rl eval) | estimate: the adaptive law's online estimate of "
                   "them (deployable; --controller adaptive_computed_torque) (default none)")
    p.add_argument("--observe-disturbance", dest="observe_disturbance", action="store_true",
                   help="the policy also observes the torque disturbance mpc's Kalman filter estimates (mpc_filter "
                   "shadowing the loop; --batched with --settle)")
    p.add_argument("--history", type=int, default=0, help="previous observations the policy also sees, latest "
                   "first (default 0)")
    p.add_argument("--observation-scaling", dest="observation_scaling", default="running",
                   help="running (VecNormalize's running statistics) | fixed (errors as the PID torque they make, "
                   "in units of the residual scale; positions by pi rad, velocities by pi rad/s; docs/design.md) "
                   "(default running)")
    p.add_argument("--reward-baseline", dest="reward_baseline", default="none",
                   help="none | controller: train on the advantage over the control law alone on the same episode "
                   "(a shadow run; 'pid' is its earlier name, whatever the law); validation and evaluation still "
                   "score J_exec (default none)")
    p.add_argument("--plant-randomization", dest="plant_randomization", default="none",
                   help="none | mismatch: train and validate on plants drawn by the mismatch family's rules "
                   "(default none)")
    p.add_argument("--planner", default="cubic", help="planner whose references the policy tracks (default cubic)")
    p.add_argument("--batched", action="store_true", help="with --algo ppo: skrl's PPO on hundreds of sub-envs of "
                   "the native vector env, on a mixture of families (mjtraj.rl.batched; defaults: 10,000,000 steps, "
                   "512 sub-envs, the adaptive law, --families nominal,aggressive,mismatch); --hyperparameter sets "
                   "its other settings (rollouts, epochs, minibatches, learning_rate, discount, gae_lambda, hidden)")
    p.add_argument("--families", "--family", type=names, default=["nominal", "aggressive", "mismatch"],
                   help="with --batched: the families the sub-envs are split over (default all three)")
    p.add_argument("--initial-std", dest="initial_std", type=float,
                   help="with --batched: the policy's initial action std, in units of the residual scale (default "
                   "0.1)")
    p.add_argument("--preview", type=int, help="with --batched: future reference samples the policy observes "
                   "(default 0)")
    p.add_argument("--preview-frame", dest="preview_frame", choices=("absolute", "relative", "reference"),
                   help="with --batched: relative: each preview sample minus the observed q and qd; reference: minus "
                   "q_ref and qd_ref now (default --init's, "
                   "else absolute)")
    p.add_argument("--settle", type=float,
                   help="with --batched: the episodes' settle window, s, in training and validation (default --init's, "
                   "else 0: protocol v1's episodes; 0.5: protocol v2's, scored by J_settle)")
    p.add_argument("--init", type=Path, help="with --batched: start the policy from this policy file (a distillation's "
                   "or a batched run's policy.pt or best.pt), taking its network, action and observation settings")
    p.add_argument("--patience", type=int, default=0,
                   help="with --batched: stop once this many validation points in a row have not improved the best "
                   "(default 0: run every step)")
    p.add_argument("--controller", help=f"control law the residual acts on: {laws} (or a "
                   "registered plug-in law; default pid, with --batched adaptive_computed_torque)")
    p.add_argument("--task", default="random", help="random (a new move each episode) | paper (default random)")
    p.add_argument("--steps", type=int, help="environment steps (default 100000; with --batched 10000000)")
    p.add_argument("--seed", type=int, default=0, help="the run's seed, 0 <= seed < 2^32 (default 0)")
    p.add_argument("--num-envs", dest="num_envs", type=int, help="sub-envs (default: 4 for sac/td3, 8 for ppo)")
    p.add_argument("--checkpoints", type=int, default=5, help="checkpoints along the run (default 5)")
    p.add_argument("--evaluations", type=int, default=20, help="validation points of the learning curve (default 20)")
    p.add_argument("--validation", type=int, default=32, help="validation tasks (default 32)")
    p.add_argument("--threads", type=int, default=1, help="PyTorch CPU threads (default 1, as in the Python API: "
                   "small networks run fastest on one, and runs can go side by side; recorded in run.json)")
    p.add_argument("--hyperparameter", dest="hyperparameter", action="append", default=[], metavar="NAME=VALUE",
                   help="an SB3 argument replacing the default (VALUE as JSON, else a string); repeat for several")
    p.add_argument("--hyperparameters", type=Path, metavar="FILE",
                   help="a JSON object of SB3 arguments replacing the defaults (--hyperparameter wins)")
    p.add_argument("--out", type=Path, default=Path("runs/rl"), help="output folder (default runs/rl)")
    p.add_argument("--resume", type=Path, metavar="RUN", help="continue the interrupted run in RUN from its last "
                   "checkpoint (a batched run's: its last validation point, resume.pt), with the settings it "
                   "recorded (the other training flags are not read); on the same machine and thread count it ends "
                   "with the policy an uninterrupted run would have")
    p.add_argument("--tensorboard", type=Path, metavar="DIR",
                   help="also log to TensorBoard event files in DIR (SB3's logger; needs the tensorboard package)")
    no_progress_option(p)
    p.set_defaults(handler=run_train)
    p = rl_sub.add_parser("search", help="Optuna's search over the batched PPO recipe's settings, and over imitation "
                          "and imitation then PPO (--learners), on the training and validation streams: study.db "
                          "(resumable), trial_K/, trials.csv, best.json")
    p.add_argument("--learners", type=names, default=["ppo"],
                   help="what a trial may train, comma-separated: ppo, distill (imitation of mpc), both (imitation "
                   "on half the budget, then PPO from it); several: sampled too (default ppo)")
    p.add_argument("--settle", type=float, default=0.0,
                   help="the episodes' settle window, s, in training and validation (0.5: protocol v2's; default 0, "
                   "v1's)")
    p.add_argument("--trials", type=int, default=12, help="trials to run now (default 12; more continue the study)")
    p.add_argument("--steps", type=int, default=1_000_000, help="env steps per trial (default 1,000,000)")
    p.add_argument("--num-envs", dest="num_envs", type=int, help="sub-envs per trial (default 512)")
    p.add_argument("--controller", help="the law the residual acts on (default adaptive_computed_torque)")
    p.add_argument("--families", "--family", type=names, default=["nominal", "aggressive", "mismatch"],
                   help="the families trained and validated on (default all three)")
    p.add_argument("--seed", type=int, default=0, help="the trials' training seed and the sampler's (default 0)")
    p.add_argument("--evaluations", type=int, default=5, help="validation points per trial (default 5; the pruner "
                   "compares trials there)")
    p.add_argument("--validation", type=int, default=32, help="validation tasks per family (default 32)")
    p.add_argument("--threads", type=int, default=1, help="PyTorch CPU threads (default 1)")
    p.add_argument("--out", type=Path, default=Path("runs/search"), help="output folder (default runs/search)")
    no_progress_option(p)
    p.set_defaults(handler=run_search)
    p = rl_sub.add_parser("distill", help="imitate a control law: behaviour cloning, then DAgger, of a residual "
                          "policy on the native vector env's training streams (mjtraj.rl.distill); policy.pt (the last "
                          "round's), best.pt (the best validated round's: rl eval --policy RUN/best.pt scores it), "
                          "learning_curve.csv, run.json, resume.pt")
    p.add_argument("--teacher", default="mpc", help="the control law imitated (default mpc)")
    p.add_argument("--controller", default="adaptive_computed_torque",
                   help="the law the residual acts on (default adaptive_computed_torque)")
    p.add_argument("--residual-scale", dest="residual_scale", type=float, default=60.0,
                   help="N m per unit of action (default 60: up to the saturation)")
    p.add_argument("--families", "--family", type=names, default=["nominal", "aggressive", "mismatch"],
                   help="the families the sub-envs are split over (default all three)")
    p.add_argument("--num-envs", dest="num_envs", type=int, default=24, help="sub-envs (default 24)")
    p.add_argument("--rounds", type=int, default=4, help="data-collection rounds: the teacher's, then DAgger's "
                   "(default 4)")
    p.add_argument("--steps", type=int, default=150, help="steps of every sub-env per round (default 150)")
    p.add_argument("--epochs", type=int, default=30, help="passes over the data after each round (default 30)")
    p.add_argument("--hidden", type=widths, default=[256, 256, 256],
                   help="hidden layer widths, comma-separated, or none: a linear student (default 256,256,256)")
    p.add_argument("--preview", type=int, default=10, help="future reference samples observed (default 10)")
    p.add_argument("--preview-frame", dest="preview_frame", choices=("absolute", "relative", "reference"),
                   default="absolute",
                   help="relative: each preview sample minus the observed q and qd; reference: minus q_ref and qd_ref "
                   "now (default absolute)")
    p.add_argument("--action-mode", dest="action_mode", choices=("residual", "torque"), default="residual",
                   help="residual: the student adds to --controller's command; torque: it commands the whole "
                   "corrective torque (default residual)")
    p.add_argument("--observe-task", dest="observe_task", action="store_true",
                   help="also observe the move and the time to the motion's end (UR5Track-v2's observation)")
    p.add_argument("--observe-control", dest="observe_control", action="store_true",
                   help="also observe the PID integral of e and the next feedforward torque (the integral runs "
                   "under --controller pid)")
    p.add_argument("--observe-plant", dest="observe_plant", choices=("none", "estimate"), default="none",
                   help="estimate: also observe the adaptive law's estimate of the plant (default none)")
    p.add_argument("--observe-disturbance", dest="observe_disturbance", action="store_true",
                   help="also observe the torque disturbance mpc's Kalman filter estimates (mpc_filter shadowing the "
                   "loop: the estimate mpc plans from, at the cost of a filter step)")
    p.add_argument("--history", type=int, default=0, help="previous observations also observed (default 0)")
    p.add_argument("--output", choices=("linear", "cubic"), default="linear",
                   help="cubic: the action is the cube of the network's output, which learns the labels' cube roots "
                   "(finer near 0) (default linear)")
    p.add_argument("--anchor", choices=("none", "disturbance"), default="none",
                   help="disturbance: the action adds the torque that cancels mpc's filtered disturbance (needs "
                   "--observe-disturbance and --action-mode torque); the network learns the rest (default none)")
    p.add_argument("--features", choices=("none", "error_over_move"), default="none",
                   help="error_over_move: the network also reads the position error over the task's move (the "
                   "score's and the settling band's unit; needs --observe-task) (default none)")
    p.add_argument("--structure", choices=("none", "gain", "gain_beyond", "gain_full"), default="none",
                   help="gain: the network outputs an offset k and a gain matrix K from the observation without q, "
                   "qd, e and ed, and the action is k + K [e; ed] (needs --output linear, --preview-frame absolute "
                   "or reference, --history 0); gain_beyond: k and K also read how far e and ed lie beyond three "
                   "standard deviations; gain_full: k and K from the whole observation (default none)")
    p.add_argument("--mixing", type=float, default=0.0,
                   help="DAgger's beta: in round r the teacher acts with probability MIXING^r (default 0: the student)")
    p.add_argument("--action-noise", dest="action_noise", type=float, default=0.0,
                   help="N m: a Gaussian torque of this standard deviation added to every action the collection "
                   "applies (where --noise-on says), in every round, labelled by the teacher where it leads (DART) "
                   "(default 0: none)")
    p.add_argument("--noise-on", dest="noise_on", choices=("all", "teacher"), default="all",
                   help="teacher: add --action-noise to the teacher's actions alone (round 0's, and those --mixing "
                   "lets it apply) (default all)")
    p.add_argument("--change-weight", dest="change_weight", type=float, default=0.0,
                   help="weight of a second loss term: the network's change between a sub-env's consecutive "
                   "periods against the labels' change (the teacher's gain along the data, not only its value) "
                   "(default 0: none)")
    p.add_argument("--decay", action="store_true",
                   help="anneal the learning rate by a cosine over each round's epochs (default constant)")
    p.add_argument("--balance", choices=("none", "family", "family-hold"), default="none",
                   help="family: each family's squared errors divided by its mean squared label; family-hold: by that "
                        "of its family and phase (the motion, the settle window) (default none)")
    p.add_argument("--validation", type=int, default=24,
                   help="validation tasks per family scored after every round, paired with the law alone; best.pt "
                   "is the best round (default 24; 0: none, best.pt is the last round)")
    p.add_argument("--validate-versus", dest="validate_versus", choices=("law", "teacher"), default="law",
                   help="teacher: validation pairs the student with the teacher alone (ratios and missed episodes "
                   "over the ruler it imitates) instead of the law alone (default law)")
    p.add_argument("--seed", type=int, default=0, help="the training streams' seed (default 0)")
    p.add_argument("--threads", type=int, default=1, help="PyTorch CPU threads (default 1)")
    p.add_argument("--out", type=Path, default=Path("runs/distill"), help="output folder (default runs/distill)")
    p.add_argument("--resume", action="store_true", help="continue the distillation saved in --out")
    no_progress_option(p)
    p.set_defaults(handler=run_distill)
    p = rl_sub.add_parser("plan", help="fit a plan policy to mpc's executions (mjtraj.rl.plan_train): mpc executes "
                          "training-stream tasks on the nominal plant, a network learns its plan as an offset from "
                          "the held cubic, and computed torque tracks the plan with its tracker's gains and "
                          "disturbance estimate subtracted; policy.npz (rl eval --policy RUN/policy.npz scores it), "
                          "run.json, labels.npz (reused when run again on the same folder with the same task "
                          "settings; so is the fitted network, with the same fit settings)")
    p.add_argument("--families", "--family", type=names, default=["nominal", "aggressive", "mismatch"],
                   help="families whose rules draw the training tasks, comma-separated (default "
                   "nominal,aggressive,mismatch)")
    p.add_argument("--tasks", type=int, default=2000, help="training tasks per family (default 2000)")
    p.add_argument("--epochs", type=int, default=160, help="passes over the labelled samples (default 160)")
    p.add_argument("--batch", type=int, default=512, help="samples per gradient step (default 512)")
    p.add_argument("--learning-rate", dest="learning_rate", type=float, default=1e-3,
                   help="Adam's initial step, decayed by a cosine (default 1e-3)")
    p.add_argument("--hidden", type=widths, default=[256, 256, 256],
                   help="hidden layer widths, comma-separated (default 256,256,256)")
    p.add_argument("--weighting", choices=("task", "family"), default="task",
                   help="what a task's squared errors are divided by: task, its own J_settle under mpc and its "
                   "samples; family, its family's mean J_settle (the loss reads as the benchmark's ratio of means) "
                   "(default task)")
    p.add_argument("--tracker", choices=("lqr", "computed_torque"), default="lqr",
                   help="how the policy follows its plan: lqr, computed torque with the finite-horizon LQR gains of "
                   "the score's own weights, the plan's offsets tapered to zero over the settle window and its own "
                   "disturbance estimate; computed_torque, CT's fixed gains, no taper and mpc_filter's estimate, "
                   "observed (plan files of format 1); it does not change the fit (default lqr)")
    p.add_argument("--seed", type=int, default=0, help="the training streams' seed and the fit's (default 0)")
    p.add_argument("--threads", type=int, default=1, help="PyTorch CPU threads (default 1)")
    p.add_argument("--workers", type=int, default=1,
                   help="processes that run mpc for the labels (the labels do not depend on it; default 1)")
    p.add_argument("--out", type=Path, default=Path("runs/plan"), help="output folder (default runs/plan)")
    no_progress_option(p)
    p.set_defaults(handler=run_plan)
    p = rl_sub.add_parser("plot", help="redraw a run's learning_curve.png from its learning_curve.csv (also of a run "
                          "still going or interrupted)")
    p.add_argument("run", type=Path, help="the folder rl train wrote")
    figure_format_option(p)
    p.set_defaults(handler=run_plot)
    p = rl_sub.add_parser("eval", help="the benchmark protocol: any policies beside the planners under every control "
                          "law on the same held-out scenarios; eval.csv, summary.json, SUMMARY.md, profiles.png, "
                          "intervals.png")
    figure_format_option(p)
    p.add_argument("--policy", dest="policies", action="append", default=[],
                   help="PATH.zip (rl train's), baseline:NAME (mjtraj rl baselines), MODULE:ATTR or FILE.py:ATTR (a "
                   "callable or torch module; docs/benchmark.md); repeat for several; none: the classical methods")
    p.add_argument("--baselines", action="store_true", help="also score every shipped baseline (mjtraj rl baselines)")
    p.add_argument("--policy-env", dest="policy_env", action="append", default=[], metavar="KEY=VALUE",
                   help="an env setting for policies without an mjtraj record (callables, torch modules, plain SB3 "
                   "zips) that do not declare it (planner, controller, action_mode, residual_scale, observe_control, "
                   "preview, preview_frame, observe_plant, history, observe_task, observe_measured; default "
                   "UR5Track-v1's); repeatable")
    p.add_argument("--protocol", choices=tuple(PROTOCOLS), default=PROTOCOL,
                   help=f"the benchmark protocol (default {PROTOCOL}: each episode goes on for a settle window after "
                   "its motion, scored over it by J_settle and held to the at-rest rule, against cubic+adaptive CT; "
                   "v1: J_exec over the motion and the goal rule, against cubic+PID; docs/benchmark.md)")
    p.add_argument("--family", "--families", type=names, default=None,
                   help="families, comma-separated: nominal, aggressive, mismatch, noisy (default the protocol's: "
                   f"{', '.join(PROTOCOL_V2['families'])} in v2, the first three in v1)")
    p.add_argument("--scenarios", type=int, default=None,
                   help=f"held-out scenarios per family (default the protocol's, {PROTOCOL_V2['scenarios']})")
    p.add_argument("--seed", type=int, default=None,
                   help=f"the scenarios' seed (default the protocol's, {PROTOCOL_V2['seed']}: held out from sweeps "
                   "and training, seed 0); any other family, count, seed or --reps is stamped off-protocol in "
                   "SUMMARY.md and summary.json")
    p.add_argument("--planners", type=names, default=["cubic"],
                   help="planners scored under each control law (cubic, the reference's, always; default cubic)")
    p.add_argument("--controllers", type=names, default=["pid"],
                   help=f"control laws the planners run under, comma-separated: {laws} or registered plug-ins "
                   "(pid always; each policy also runs on its own)")
    p.add_argument("--tuned-gains", dest="tuned_gains", type=Path,
                   help="a scenario file from `mjtraj tune --gains`, scored as 'cubic+PID (tuned gains)'")
    p.add_argument("--floor", action="store_true", help="also compute each scenario's clairvoyant floor and read "
                   "every method against it and against the strongest classical method (floor.csv; under protocol v2 "
                   "the least J_settle at rest at the goal, on the mismatch plants also without each law's own start)")
    p.add_argument("--versus", metavar="METHOD", action="append",
                   help="also pair every method against this one of the evaluation (e.g. \"cubic+adaptive CT\"): "
                   "J / its J and P(better), with intervals, in SUMMARY.md; repeat it to pair against several (one "
                   "run, one table each: labels may hold commas)")
    p.add_argument("--reps", type=int, default=None,
                   help=f"bootstrap resamples per interval (default the protocol's, {PROTOCOL_V2['reps']})")
    p.add_argument("--threads", type=int, default=1, help="PyTorch CPU threads (default 1, the rule of rl train)")
    p.add_argument("--out", type=Path, default=Path("rl_eval"), help="output folder (default rl_eval/)")
    p.add_argument("--keep-going", dest="keep_going", action="store_true",
                   help="a policy that raises or returns actions of the wrong shape or non-finite ones gets error rows "
                   "(counted in SUMMARY.md) instead of stopping the run with its error (exit 2)")
    no_progress_option(p)
    p.set_defaults(handler=run_eval)
    p = rl_sub.add_parser("baselines", help="list the shipped trained policies (use them as --policy baseline:NAME)")
    p.set_defaults(handler=run_baselines)
    p = rl_sub.add_parser("best", help="choose baseline:best on validation scenarios (never evaluation ones) by "
                             "the stated rule and write it, with every score, into the baselines' BEST.json")
    p.add_argument("--scenarios", type=int, default=100, help="validation scenarios per family (default 100)")
    p.add_argument("--protocol", choices=tuple(PROTOCOLS), default=PROTOCOL,
                   help=f"the protocol the choice is scored on (default {PROTOCOL}: J_settle over the settle window, "
                   "held to the at-rest rule, beside cubic+adaptive CT; v1: J_exec and the goal rule beside "
                   "cubic+PID, the rule of the choices made before v2, written to BEST_v1.json: baseline:best stays "
                   "v2's)")
    no_progress_option(p)
    p.set_defaults(handler=run_best)
    p = rl_sub.add_parser("ship", help="ship a run's policy as a baseline: its zip without optimiser states (the same "
                          "actions, checked), its record and run.json; a batched run's policy.pt with its run.json "
                          "and learning curve; a plan run's policy.npz with its run.json")
    p.add_argument("run", type=Path, help="the folder rl train or rl plan wrote")
    p.add_argument("--name", required=True, help="the baseline's name (letters, digits, _ and -)")
    p.add_argument("--which", default="best", help="best (selected on validation; default) | policy (the final "
                   "one); a plan run has its policy only")
    p.add_argument("--into", type=Path, help="folder of baselines (default: the package's own, mjtraj/rl/baselines)")
    p.add_argument("--student", action="store_true", help="ship a privileged teacher (--observe-plant true on the "
                   "adaptive law) as its deployable student: the same weights observing the adaptive law's estimate")
    p.set_defaults(handler=run_ship)
    p = rl_sub.add_parser("ensemble", help="combine policies of rl distill or rl train --batched that act in one env "
                          "into one deployable policy: the mean of their actions, inferred in NumPy (score it with rl "
                          "eval --policy OUT)")
    p.add_argument("members", nargs="+", type=Path, help="the members' policy files (RUN/best.pt or RUN/policy.pt)")
    p.add_argument("--out", type=Path, required=True, help="the ensemble's file to write (FILE.pt)")
    p.set_defaults(handler=run_ensemble)


def _list(parser: argparse.ArgumentParser) -> int:
    parser.print_help()
    return 0


def run_plot(args: argparse.Namespace) -> int:
    """`mjtraj rl plot`."""
    from mjtraj.rl.train import plot_run

    print(f"wrote {plot_run(args.run, formats=tuple(args.figure_format))}")
    return 0


def run_train(args: argparse.Namespace) -> int:
    """`mjtraj rl train`."""
    from mjtraj.rl.extra import require_sb3

    if args.batched or (args.resume is not None and (args.resume / "resume.pt").is_file()):
        return _run_batched(args)
    if args.observe_disturbance:
        from mjtraj.exceptions import InvalidInputError

        raise InvalidInputError("observe_disturbance: only batched training (--batched --settle S) runs mpc's filter "
                                "beside the loop; add --batched")
    require_sb3()
    from mjtraj.rl.train import TrainSettings, resume_training, train

    if args.resume is not None:
        report = resume_training(args.resume, progress=not args.no_progress, tensorboard=args.tensorboard)
        print(f"resumed {args.resume} and trained to {report.timesteps} steps; validation mean J_exec "
              f"{report.final['cost_mean']:.4g}")
        print(f"wrote {report.policy}")
        return 0

    extra: dict[str, Any] = {} if args.residual_scale is None else {"residual_scale": args.residual_scale}
    extra["overrides"] = overrides(args.hyperparameters, args.hyperparameter)
    extra["observe_control"] = args.observe_control
    extra["observe_plant"] = args.observe_plant
    extra["history"] = args.history
    extra["observation_scaling"] = args.observation_scaling
    extra["plant_randomization"] = args.plant_randomization
    extra["reward_baseline"] = args.reward_baseline
    settings = TrainSettings(algo=args.algo, action_mode=args.action_mode, **extra, planner=args.planner,
                             controller=args.controller or "pid", task=args.task,
                             steps=100_000 if args.steps is None else args.steps, seed=args.seed,
                             num_envs=args.num_envs,
                             checkpoints=args.checkpoints, evaluations=args.evaluations,
                             validation=args.validation, threads=args.threads)
    report = train(settings, args.out, progress=not args.no_progress, tensorboard=args.tensorboard)
    final = report.final
    print(f"trained {report.timesteps} steps in {report.wall:.0f} s; validation mean J_exec "
          f"{final['cost_mean']:.4g} (median {final['cost_median']:.4g}, {final['diverged']} diverged)")
    print(f"wrote {report.policy}, {report.out / 'best.zip'} (best on validation), "
          f"{report.out / 'learning_curve.csv'}, {report.out / 'learning_curve.png'}, {report.out / 'run.json'} "
          f"and {report.out / 'checkpoints'}/")
    return 0


def _missed(point: dict[str, float]) -> str:
    """What a protocol-v2 validation point says besides its ratio: the episodes missed where the law came to rest
    (the ratio is over the episodes both came to rest on); '' for a v1 point."""
    if "missed" not in point:
        return ""
    return f" on the episodes both came to rest on, {point['missed']:.0f} missed where the law came to rest"


def _run_batched(args: argparse.Namespace) -> int:
    """`mjtraj rl train --algo ppo --batched`."""
    from mjtraj.exceptions import InvalidInputError
    from mjtraj.rl.batched import BatchedSettings, init_defaults, resume_batched, train_batched

    if args.resume is not None:
        report = resume_batched(args.resume, progress=not args.no_progress)
        print(f"resumed {args.resume} and trained to {report.timesteps} steps; best validation point: the worst "
              f"family's mean {report.score} {report.best_point.get('worst_ratio', float('nan')):.4f} of the law "
              f"alone's{_missed(report.best_point)}")
        print(f"wrote {report.policy}, {report.best} (best on validation), {report.curve} and "
              f"{report.out / 'run.json'}")
        return 0
    if args.algo != "ppo":
        raise InvalidInputError(f"batched: trains PPO (skrl's); got --algo {args.algo}")
    tuned = overrides(args.hyperparameters, args.hyperparameter)
    if {"study", "best"} <= set(tuned):  # a search's best.json: its best trial's settings
        from mjtraj.rl.search import best_settings

        tuned = {**best_settings(args.hyperparameters), **overrides(None, args.hyperparameter)}
    allowed = {"rollouts", "epochs", "minibatches", "learning_rate", "discount", "gae_lambda", "hidden",
               "initial_std", "residual_scale", "preview", "observe_control"}
    unknown = sorted(set(tuned) - allowed)
    if unknown:
        raise InvalidInputError(f"hyperparameter: unknown name {unknown[0]!r} for --batched; valid: "
                                f"{', '.join(sorted(allowed))}")
    if "hidden" in tuned:
        tuned["hidden"] = tuple(tuned["hidden"]) if isinstance(tuned["hidden"], list) else tuned["hidden"]
    given = {"steps": args.steps, "num_envs": args.num_envs, "controller": args.controller}
    flags = {"residual_scale": args.residual_scale, "initial_std": args.initial_std, "preview": args.preview,
             "observe_control": args.observe_control or None, "history": args.history or None,
             "observe_disturbance": args.observe_disturbance or None,
             "observe_plant": None if args.observe_plant == "none" else args.observe_plant,
             "action_mode": None if args.action_mode == "residual" else args.action_mode, "settle": args.settle,
             "preview_frame": args.preview_frame}
    started = init_defaults(args.init) if args.init else {}
    settings = BatchedSettings(**{**started, **{k: v for k, v in given.items() if v is not None}, **tuned,
                                  **{k: v for k, v in flags.items() if v is not None},
                                  "families": tuple(args.families), "seed": args.seed, "threads": args.threads,
                                  "evaluations": args.evaluations, "validation": args.validation,
                                  "patience": args.patience, "init": str(args.init) if args.init else ""})
    report = train_batched(settings, args.out, progress=not args.no_progress, command=command_line(args))
    point = report.best_point
    print(f"trained {report.timesteps} steps in {report.wall:.0f} s ({report.timesteps / report.wall:.0f} steps/s); "
          f"best validation point at {point.get('timesteps', 0):.0f} steps: the worst family's mean {report.score} "
          f"{point.get('worst_ratio', float('nan')):.4f} of the law alone's{_missed(point)}")
    if report.stopped:
        print(f"stopped at {report.timesteps} steps: {report.stopped}")
    print(f"wrote {report.policy}, {report.best} (best on validation), {report.curve} and {report.out / 'run.json'}")
    return 0


def run_distill(args: argparse.Namespace) -> int:
    """`mjtraj rl distill`."""
    from mjtraj.rl.distill import DistillSettings, distill, resume_distill

    if args.resume:
        report = resume_distill(args.out, progress=not args.no_progress)
    else:
        settings = DistillSettings(teacher=args.teacher, controller=args.controller,
                                   residual_scale=args.residual_scale, families=tuple(args.families),
                                   num_envs=args.num_envs, rounds=args.rounds, steps=args.steps, epochs=args.epochs,
                                   hidden=tuple(args.hidden), preview=args.preview,
                                   preview_frame=args.preview_frame, action_mode=args.action_mode,
                                   observe_task=args.observe_task, observe_control=args.observe_control,
                                   observe_plant=args.observe_plant,
                                   observe_disturbance=args.observe_disturbance,
                                   history=args.history, output=args.output, features=args.features,
                                   anchor=args.anchor, structure=args.structure,
                                   mixing=args.mixing, action_noise=args.action_noise, noise_on=args.noise_on,
                                   change_weight=args.change_weight, decay=args.decay,
                                   balance=args.balance, validation=args.validation,
                                   validate_versus=args.validate_versus, seed=args.seed, threads=args.threads)
        report = distill(settings, args.out, progress=not args.no_progress, command=command_line(args))
    print(f"wrote {report.policy} (the last round's, {int(report.rounds[-1]['samples'])} labelled states) and "
          f"{report.best} (the best validated round's); score one: mjtraj rl eval --policy {report.best}")
    return 0


def run_plan(args: argparse.Namespace) -> int:
    """`mjtraj rl plan`."""
    from mjtraj.rl.plan_train import PlanSettings, train_plan

    settings = PlanSettings(families=tuple(args.families), tasks=args.tasks, epochs=args.epochs, batch=args.batch,
                            learning_rate=args.learning_rate, hidden=tuple(args.hidden), weighting=args.weighting,
                            seed=args.seed, threads=args.threads, workers=args.workers, tracker=args.tracker)
    report = train_plan(settings, args.out, progress=not args.no_progress, command=command_line(args))
    seconds = report.record["seconds"]
    print(f"wrote {report.policy} ({report.record['samples']} labelled samples; labels {seconds['labels']:.0f} s, "
          f"fit {seconds['fit']:.0f} s); score it: mjtraj rl eval --protocol v2 --policy {report.policy}")
    return 0


def run_search(args: argparse.Namespace) -> int:
    """`mjtraj rl search`."""
    from mjtraj.rl.batched_policy import BatchedSettings
    from mjtraj.rl.search import search

    base = BatchedSettings(**{k: v for k, v in {"steps": args.steps, "num_envs": args.num_envs,
                                                "controller": args.controller}.items() if v is not None},
                           families=tuple(args.families), seed=args.seed, threads=args.threads,
                           evaluations=args.evaluations, validation=args.validation, settle=args.settle)

    def line(trial: dict[str, object]) -> None:
        value = trial["value"]
        shown = f"{value:.4f}" if isinstance(value, float) else "-"
        print(f"trial {trial['number']:>3} {trial['state']:<8} worst family {shown} of the law alone, "
              f"{trial['timesteps']} steps: {json.dumps(trial['settings'])}", flush=True)

    report = search(base, args.out, trials=args.trials, progress=not args.no_progress, on_trial=line,
                    learners=tuple(args.learners))
    print(f"{report.trials} trials in the study ({report.episodes} PPO training and {report.validation_episodes} "
          f"validation episodes in all); best: {json.dumps(report.best)}")
    if report.best.get("learner", "ppo") == "ppo":
        print(f"wrote {report.out / 'trials.csv'} and {report.out / 'best.json'}; train with it: mjtraj rl train "
              f"--algo ppo --batched --hyperparameters {report.out / 'best.json'}")
    else:
        print(f"wrote {report.out / 'trials.csv'} and {report.out / 'best.json'}; score the best trial's policy: "
              f"mjtraj rl eval --policy {report.best['policy']}")
    return 0


def run_baselines(args: argparse.Namespace) -> int:
    """`mjtraj rl baselines`."""
    from mjtraj.rl.baselines import baseline_names, describe

    for name in baseline_names():
        facts = describe(name)
        if facts["algo"] == "plan":
            print(f"baseline:{name}  {facts['label']}, seed {facts['seed']}: a plan fitted to mpc's executions "
                  f"(mjtraj rl plan)")
            continue
        print(f"baseline:{name}  {facts['algo'].upper()} seed {facts['seed']}, the checkpoint at "
              f"{facts['timesteps']:,} of {facts['settings']['steps']:,} trained steps (best on validation), "
              f"controller {facts['env'].get('controller', 'pid')}, plants {facts['env']['plant_randomization']}")
    return 0


def run_best(args: argparse.Namespace) -> int:
    """`mjtraj rl best`."""
    from mjtraj.checks import positive_int
    from mjtraj.rl.baselines import baseline_names, baselines_folder
    from mjtraj.rl.best import BEST_FILES, choose_best

    positive_int("scenarios", args.scenarios)
    command = command_line(args)
    with Progress("mjtraj rl best", "baseline", not args.no_progress) as progress:
        chosen = choose_best(baselines_folder(), baseline_names(), scenarios=args.scenarios, protocol=args.protocol,
                             command=command, progress=progress)
    for name, scores in chosen["scores"].items():
        print(f"{name}: " + ", ".join(f"{f} {r if isinstance(r, str) else format(r, '.4g')}"
                                      for f, r in scores.items()))
    if args.protocol == PROTOCOL:
        print(f"baseline:best = {chosen['best']} ({chosen['rule']})")
    else:
        print(f"protocol {args.protocol}'s rule chooses {chosen['best']} ({chosen['rule']}); written to "
              f"{BEST_FILES[args.protocol]}, baseline:best unchanged")
    return 0


def run_ship(args: argparse.Namespace) -> int:
    """`mjtraj rl ship`."""
    from mjtraj.checks import choice
    from mjtraj.rl.baselines import ship

    choice("which", args.which, ("best", "policy"))
    print(f"wrote {ship(args.run, args.name, which=args.which, into=args.into, student=args.student)}")
    return 0


def run_ensemble(args: argparse.Namespace) -> int:
    """`mjtraj rl ensemble`."""
    from mjtraj.rl.ensemble import write_ensemble

    print(f"wrote {write_ensemble(args.members, args.out)} (the mean of {len(args.members)} policies)")
    return 0


def _versus(given: list[str] | None) -> str | tuple[str, ...] | None:
    """--versus as evaluate takes it: one method (its summary as it always was), several, or none."""
    if not given:
        return None
    return given[0] if len(given) == 1 else tuple(given)


def run_eval(args: argparse.Namespace) -> int:
    """`mjtraj rl eval`."""
    from mjtraj.exceptions import InvalidInputError, UnnamedPolicyEnvError

    command = command_line(args)
    policies = list(args.policies)
    if args.baselines:
        from mjtraj.rl.baselines import baseline_names

        policies += [f"baseline:{name}" for name in baseline_names()]
    try:
        evaluation = _evaluate(args, policies, command)
    except UnnamedPolicyEnvError as e:  # the user's own command, with what it lacks
        import shlex

        example = "mjtraj " + " ".join(shlex.quote(a) for a in [*args.argv, *e.flags])
        raise InvalidInputError(f"{e.reason}, e.g. {example}") from e
    print(f"Protocol {evaluation.protocol}, OFF-PROTOCOL ({'; '.join(evaluation.departures)}): these numbers "
          "cannot be compared with published ones." if evaluation.departures else f"Protocol {evaluation.protocol}.")
    print()
    print(evaluation.table)
    print(f"\nIn short (J / {evaluation.reference}, then P(improve)):\n")
    print(evaluation.compact)
    if evaluation.executions:
        print("\nWhat the executions did:\n")
        print(evaluation.executions)
        print(f"\n{evaluation.weighting}")
    if evaluation.floor_table:
        print("\nAgainst the floor and the strongest classical method:\n")
        print(evaluation.floor_table)
    if evaluation.errors:
        print("\nRows whose evaluation raised (status error), by reason:\n")
        print("\n".join(f"- {count} x {reason}" for reason, count in evaluation.errors.items()))
    figures = f"{evaluation.figure}" + (f" and {evaluation.intervals}" if evaluation.intervals else "")
    print(f"\nwrote {evaluation.csv}, {evaluation.summary_json}, {evaluation.markdown}, {figures}")
    return 0


def _evaluate(args: argparse.Namespace, policies: list[Any], command: str) -> Any:
    """`rl eval`'s evaluation with the command's options."""
    from mjtraj.rl.evaluate import evaluate

    return evaluate(policies, families=None if args.family is None else tuple(args.family),
                    scenarios=args.scenarios, seed=args.seed, protocol=args.protocol,
                    planners=tuple(args.planners), controllers=tuple(args.controllers),
                    tuned_gains=args.tuned_gains, reps=args.reps, threads=args.threads,
                    settings=overrides(None, args.policy_env, "policy-env"), out=args.out, command=command,
                    progress=not args.no_progress, floor=args.floor,
                    figure_formats=tuple(args.figure_format), versus=_versus(args.versus),
                    keep_going=args.keep_going)
