"""Export a run's policy: `python -m experiments.export RUN_DIR [--out DIR]`.

From the run's latest checkpoint, writes into RUN_DIR/export/ (or --out):
  policy.npz         weights and observation normaliser; `jaxarm.export.numpy_policy.load(path)(obs)` runs it
                     with numpy alone
  policy.jax_export  the learner's own `act`, serialised by jax.export (CPU and CUDA);
                     `jax.export.deserialize(data).call(obs)` runs it for any batch size
  policy.onnx        the same as an ONNX model, when jax2onnx is installed (`pip install -e ".[export]"`)
  deploy.json, robot.mjb   for the sorter and the peg (state or cameras): the deployment loop's task and the
                     scene it poses the arm in; `jaxarm.deploy.files.load(dir)` builds its controller without JAX
  export.json        which checkpoint the policy came from (its update count): `experiments.transfer` names its
                     results by it
Every form maps observations to deterministic actions: flat ones float32 [B, O] (or [O] for the numpy policy), a
camera's as their parts by name (the uint8 image [B, H, W, C], the float32 proprio [B, P] where the env observes
one; the ONNX model's inputs are named "image" and "proprio", the numpy policy and jax.export module take a dict).
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c(start_up.AT_ONCE)  # first: Ctrl-C ends it at once, from its first import on

import argparse
import pathlib

from jaxarm import deployable
from jaxarm.agents.common import checkpoint
from jaxarm.deploy import files as deploy_files
from jaxarm.export import origin, policy
from jaxarm.runner import learners, paths, rundir


def export_run(run_dir: pathlib.Path, out_dir: pathlib.Path) -> list[pathlib.Path]:
    """Writes the exported forms of `run_dir`'s latest policy into `out_dir`; returns the files written.

    Raises ValueError (or CheckpointError) naming what is wrong before anything is written.
    """
    config, _ = rundir.read_config(run_dir)
    env, _ = config.make_env()
    if env.spec.flat_observation:
        policy.check_flat_observations(env.spec)
    trainer = learners.make_trainer(config, run_dir)
    state = learners.restore_state(run_dir, trainer, config, acting=True)
    arrays = policy.numpy_policy(trainer, state)
    serialized = policy.serialized_jax_policy(trainer, state, env.spec)
    try:
        onnx_model: bytes | None = policy.onnx_policy(trainer, state, env.spec)
    except ImportError:
        onnx_model = None
    eval_env, eval_params = config.make_eval_env()
    controller = deployable.controller(eval_env, eval_params) if deployable.runs(eval_env) else None
    out_dir.mkdir(parents=True, exist_ok=True)
    # Removed first and written last: an export cut short leaves no record, never one naming another checkpoint.
    (out_dir / origin.FILE).unlink(missing_ok=True)
    written = [out_dir / "policy.npz", out_dir / "policy.jax_export"]
    arrays.save(written[0])
    written[1].write_bytes(serialized)
    if onnx_model is not None:
        written.append(out_dir / "policy.onnx")
        written[2].write_bytes(onnx_model)
    if controller is not None:
        written += deploy_files.save(out_dir, controller)
    written.append(out_dir / origin.FILE)
    rundir.write_json(written[-1], origin.record(str(int(state.updates))))
    return written


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.export", description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("--out", type=paths.given, help="directory for the exported files (default RUN_DIR/export)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    run_dir = pathlib.Path(args.run_dir)
    out_dir = pathlib.Path(args.out) if args.out else run_dir / "export"
    try:
        paths.check_output_dir(out_dir, "--out")
        if (out_dir / "config.json").exists():  # its resume and eval then refused the run's foreign files
            raise rundir.RunDirError(f"--out {out_dir} is a run directory; give a folder of the export's own")
        written = export_run(run_dir, out_dir)
    except (ValueError, checkpoint.CheckpointError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"error: {paths.os_error_message(error)}", file=sys.stderr)
        return 2
    for path in written:
        print(f"wrote {path}")
    if not rundir.read_evaluation(run_dir).get("finished"):
        print(
            f"note: {run_dir} has not finished training: this is the policy of update {origin.read(out_dir)}; export "
            "again when it has"
        )
    if not any(path.name == "policy.onnx" for path in written):
        print('no policy.onnx: jax2onnx is not installed (pip install -e ".[export]")')
    return 0


if __name__ == "__main__":
    start_up.exit_with(main)
