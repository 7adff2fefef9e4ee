"""``energy-margin scene --from-gym``: a starter scene file for a Gymnasium MuJoCo environment."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

gymnasium = pytest.importorskip("gymnasium")

from energy_margin.cli import main  # noqa: E402
from energy_margin.errors import EnergyMarginError  # noqa: E402
from energy_margin.integrations.gym_scene import scene_from_environment  # noqa: E402
from energy_margin.integrations.gymnasium import mujoco_handles  # noqa: E402
from energy_margin.tasks.scene_file import read_scene_file  # noqa: E402
from energy_margin.tasks.scene_model import load_scene, model_hash  # noqa: E402


def test_pusher_starter_scene(tmp_path: Path) -> None:
    env = gymnasium.make("Pusher-v5")
    written = scene_from_environment(env, objects="object", out=tmp_path / "pusher.toml")
    assert written.objects == ("object",)
    assert written.end_effector == ("body", "tips_arm") and written.goal == ("body", "goal")
    assert written.same_model
    # The environment's own model file, copied: the scene names the XML, and no .mjb is written.
    assert written.model_file == tmp_path / "pusher.xml"
    assert written.model_note == f"wrote {tmp_path / 'pusher.xml'} (the environment's model file, same model)"
    assert sorted(path.name for path in tmp_path.iterdir()) == ["pusher.toml", "pusher.xml"]
    assert read_scene_file(written.scene_file).mjcf == written.model_file
    # The re-saved model compiles to the environment's model, and the file loads against it.
    loaded = load_scene(written.scene_file)
    assert loaded.model_sha256 == model_hash(mujoco_handles(env)[0])
    assert loaded.object_names == ("object",) and loaded.spec.object_joints == "upright"
    text = written.scene_file.read_text()
    assert "#   0: (unnamed) -> joint r_shoulder_pan_joint, ctrl in [-2, 2]" in text
    spec = read_scene_file(written.scene_file)
    assert spec.capture == {"type": "distance", "body": "tips_arm", "max": written.capture_radius}
    assert spec.motion.duration == pytest.approx(5.0)  # 100 steps of 0.05 s


def test_a_model_edited_after_make_is_saved_compiled(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # As Meta-World and Fetch do: the environment changes its model in Python after loading the XML.
    env = gymnasium.make("Pusher-v5")
    model = env.unwrapped.model
    model.body_pos[model.body("goal").id] += 0.01
    model.geom_pos[0] += 0.01
    written = scene_from_environment(env, objects="object", out=tmp_path / "pusher.toml")
    assert written.model_file == tmp_path / "pusher.mjb" and written.same_model
    assert written.model_note == (
        f"wrote {tmp_path / 'pusher.mjb'}: the environment changed its model after loading pusher_v5.xml "
        "(body_pos, geom_pos differ)"
    )
    assert sorted(path.name for path in tmp_path.iterdir()) == ["pusher.mjb", "pusher.toml"]
    # The scene file names the binary model: exactly the environment's model.
    loaded = load_scene(written.scene_file)
    assert loaded.spec.mjcf == written.model_file
    assert loaded.model_sha256 == model_hash(model)
    assert main(["scene", str(written.scene_file), "--no-picture"]) == 0
    assert f"model pusher.mjb (sha256 {model_hash(model)[:12]})" in capsys.readouterr().out


def test_a_model_without_a_file_is_saved_compiled(tmp_path: Path) -> None:
    # robosuite builds its XML in memory and gym-aloha's physics names no file: nothing to copy.
    env = gymnasium.make("Pusher-v5")
    bare = SimpleNamespace(model=env.unwrapped.model, data=env.unwrapped.data)
    written = scene_from_environment(bare, objects="object", out=tmp_path / "bare.toml")
    assert written.model_file == tmp_path / "bare.mjb"
    assert "names no model file to copy (env.unwrapped.fullpath)" in written.model_note
    assert load_scene(written.scene_file).model_sha256 == model_hash(env.unwrapped.model)
    # A model file that no longer compiles once copied: the compiled model is saved instead.
    broken = tmp_path / "broken.xml"
    broken.write_text('<mujoco><worldbody><geom type="nope"/></worldbody></mujoco>')
    env.unwrapped.fullpath = str(broken)
    written = scene_from_environment(env, objects="object", out=tmp_path / "copy" / "pusher.toml")
    assert written.model_file.suffix == ".mjb" and "the copy of broken.xml does not compile" in written.model_note
    assert sorted(path.name for path in written.scene_file.parent.iterdir()) == ["pusher.mjb", "pusher.toml"]


def test_an_edited_model_refused_by_the_scene_writes_nothing(tmp_path: Path) -> None:
    env = gymnasium.make("Pusher-v5")
    env.unwrapped.model.body_pos[1] += 0.01
    with pytest.raises(EnergyMarginError, match=r"^objects cube: no body of Pusher-v5 matches"):
        scene_from_environment(env, objects="cube", out=tmp_path / "scene" / "s.toml")
    assert not (tmp_path / "scene").exists()


def test_a_model_with_unnamed_bodies_gets_a_named_end_effector(tmp_path: Path) -> None:
    written = scene_from_environment(gymnasium.make("Ant-v5"), objects="torso", out=tmp_path / "ant.toml")
    assert written.end_effector[1] != ""
    assert written.goal is None  # then the objects must stay up
    assert read_scene_file(written.scene_file).success["type"] == "height"


def test_the_command_prints_its_guesses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "p.toml"
    assert (
        main(["scene", "--from-gym", "Pusher-v5", "--object-bodies", "object", "--out", str(out), "--no-picture"]) == 0
    )
    printed = capsys.readouterr().out
    assert f"wrote {out}\nwrote {out.with_suffix('.xml')} (the environment's model file, same model)\n" in printed
    assert "capture (a guess, edit it): within 0.191 m of body 'tips_arm'" in printed
    assert "objects (1, upright (default: read from the model))" in printed
    # The starter writes the default perturbation itself, so that it can be edited: nothing marked.
    assert "perturbation: linear acceleration (2, 2, 0) m/s^2, angular acceleration (0, 0, 20) rad/s^2, " in printed


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--from-gym", "Nope-v0", "--object-bodies", "x"], "--from-gym Nope-v0: Environment `Nope` doesn't exist"),
        (["--from-gym", "Nope/Env-v0", "--object-bodies", "x"], "give the module that registers it: MODULE:ENV_ID"),
        (["--from-gym", "no_such_module:Env-v0", "--object-bodies", "x"], "module 'no_such_module' cannot be imported"),
        (["--from-gym", "Pusher-v5", "--object-bodies", "x", "--env-kwargs", "{bad"], "--env-kwargs is not JSON"),
        (["--from-gym", "Pusher-v5", "--object-bodies", "x", "--env-kwargs", "[1]"], "must be a JSON object"),
        (
            ["--from-gym", "Pusher-v5", "--object-bodies", "x", "--env-kwargs", '{"no_such_option": 1}'],
            r"Pusher-v5 with \{'no_such_option': 1\}: TypeError: .*no_such_option",
        ),
        (["--env-kwargs", "{}"], "--env-kwargs applies to --from-gym only"),
        (["--from-gym", "CartPole-v1", "--object-bodies", "x"], r"\(CartPoleEnv\) has no MuJoCo model"),
        (["--from-gym", "Pusher-v5", "--object-bodies", "cube"], "cube: no body of Pusher-v5 matches"),
        (["--from-gym", "Pusher-v5"], "--from-gym needs --object-bodies PATTERN and --out SCENE.toml"),
        (
            ["--from-gym", "Pusher-v5", "--object-bodies", "object", "--capture-radius", "0"],
            "--capture-radius must be > 0",
        ),
        ([], "give a scene file, or --from-gym ENV_ID"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], arguments: list[str], message: str
) -> None:
    out = tmp_path / "scene" / "s.toml"
    if arguments and "--object-bodies" in arguments:
        arguments = [*arguments, "--out", str(out)]
    assert main(["scene", *arguments, "--no-picture"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and pytest.importorskip("re").search(message, error), error
    assert not out.parent.exists()


def test_module_and_keyword_arguments_reach_gymnasium_make(tmp_path: Path) -> None:
    # MODULE:ENV_ID imports the module first; --env-kwargs are gymnasium.make's keyword arguments.
    out = tmp_path / "p.toml"
    arguments = ["--from-gym", "gymnasium.envs.mujoco:Pusher-v5", "--env-kwargs", '{"frame_skip": 3}']
    assert main(["scene", *arguments, "--objects", "object", "--out", str(out), "--no-picture"]) == 0
    assert out.is_file()
    from energy_margin.integrations.gymnasium import make_environment

    env = make_environment("gymnasium.envs.mujoco:Pusher-v5", {"frame_skip": 3})
    assert env.unwrapped.frame_skip == 3


def test_the_old_objects_flag_still_names_the_bodies_with_a_note(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "p.toml"
    assert main(["scene", "--from-gym", "Pusher-v5", "--objects", "object", "--out", str(out), "--no-picture"]) == 0
    assert "--objects is now --object-bodies; the old name goes in 0.3" in capsys.readouterr().err
    assert out.is_file()
