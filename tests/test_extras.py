"""The lean core install: what needs which extra, and the message a missing extra gives."""

from __future__ import annotations

import ast
import configparser
import importlib.metadata
import json
import re
import subprocess
import sys
import textwrap
from functools import cache
from pathlib import Path

import pytest
from packaging.requirements import Requirement

from sb3_adc.extras import EXTRA_MODULES, MissingExtraError, extras_providing, import_optional, missing_extra, requires_extra

ROOT = Path(__file__).resolve().parents[1]
FIRST_PARTY = {"sb3_adc", "sb3_adc_envs"}
#: Extras of tools around the code (tests, docs) and the union of the others: not imported by the package.
TOOL_EXTRAS = {"test", "docs", "all"}


def canonical(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def requirements(value: str) -> list[Requirement]:
    lines = [line.split("#", 1)[0].strip() for line in value.splitlines()]
    return [Requirement(line) for line in lines if line]


def declared() -> tuple[set[str], dict[str, set[str]]]:
    """
    The distributions of ``install_requires`` and of each extra, from setup.cfg. An extra of a core distribution
    (``gymnasium[mujoco]``) brings that distribution's optional packages, which the extra also names where the
    code needs them: it is not counted as a second declaration of the core distribution.
    """
    parser = configparser.ConfigParser()
    parser.read(ROOT / "setup.cfg")
    core = {canonical(requirement.name) for requirement in requirements(parser["options"]["install_requires"])}

    def names(value: str) -> set[str]:
        return {
            canonical(requirement.name)
            for requirement in requirements(value)
            if not (requirement.extras and canonical(requirement.name) in core)
        }

    extras = {extra: names(value) for extra, value in parser["options.extras_require"].items()}
    return core, extras


def core_closure(core: set[str]) -> set[str]:
    """The installed distributions that the core requirements pull in, transitively (extras' markers excluded)."""
    seen: set[str] = set()
    todo = list(core)
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        try:
            requires = importlib.metadata.requires(name) or []
        except importlib.metadata.PackageNotFoundError:
            continue
        for line in requires:
            requirement = Requirement(line)
            if requirement.marker is None or requirement.marker.evaluate({"extra": ""}):
                todo.append(canonical(requirement.name))
    return seen


@cache
def installed_modules() -> dict[str, list[str]]:
    return dict(importlib.metadata.packages_distributions())


def distributions_of(module: str) -> set[str]:
    """The distributions that install a top-level module (its own name when it is not installed here)."""
    found = installed_modules().get(module)
    return {canonical(name) for name in found} if found else {canonical(module)}


def third_party_imports() -> dict[str, set[str]]:
    """Top-level module -> the files of sb3_adc/ and envs/ that import it, for every non-stdlib, non-own module."""
    imports: dict[str, set[str]] = {}
    for path in [*ROOT.joinpath("sb3_adc").rglob("*.py"), *ROOT.joinpath("envs").rglob("*.py")]:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".", 1)[0]
                if top not in sys.stdlib_module_names and top not in FIRST_PARTY:
                    imports.setdefault(top, set()).add(str(path.relative_to(ROOT)))
    return imports


def non_core_modules() -> list[str]:
    """The modules of :data:`EXTRA_MODULES` that the core install does not bring."""
    core, _ = declared()
    closure = core_closure(core)
    modules = {module for modules in EXTRA_MODULES.values() for module in modules}
    return sorted(module for module in modules if not distributions_of(module) & closure)


def test_every_imported_package_is_declared_in_setup_cfg():
    core, extras = declared()
    everything = core | set().union(*extras.values())
    undeclared = {
        module: sorted(files) for module, files in third_party_imports().items() if not distributions_of(module) & everything
    }
    assert not undeclared, f"imported but declared neither in install_requires nor in an extra: {undeclared}"


def test_extra_modules_match_the_extras_of_setup_cfg():
    core, extras = declared()
    assert set(EXTRA_MODULES) == set(extras) - TOOL_EXTRAS
    for extra, modules in EXTRA_MODULES.items():
        provided = set().union(*(distributions_of(module) for module in modules))
        unlisted = sorted(extras[extra] - provided)
        assert not unlisted, f"{extra}: setup.cfg lists {unlisted} that EXTRA_MODULES lacks"
        for module in modules:
            assert distributions_of(module) & extras[extra], f"{module} is not a package of the {extra!r} extra"
    # `all` is every extra; the core is lean: no package of an extra is a core requirement.
    assert extras["all"] == set().union(*(extras[extra] for extra in extras if extra != "all"))
    assert not core & set().union(*(extras[extra] for extra in EXTRA_MODULES))


def test_the_mujoco_extra_is_gymnasiums_with_mujoco_3():
    parser = configparser.ConfigParser()
    parser.read(ROOT / "setup.cfg")
    by_name = {canonical(r.name): r for r in requirements(parser["options.extras_require"]["mujoco"])}
    assert set(by_name) == {"gymnasium", "mujoco"}
    assert by_name["gymnasium"].extras == {"mujoco"}
    # mujoco 3, the version the constraints file pins (4 is a new major version, not checked).
    pinned = re.search(r"^mujoco==(\S+)$", ROOT.joinpath("constraints.txt").read_text(encoding="utf-8"), re.MULTILINE)
    assert pinned is not None
    assert pinned.group(1) in by_name["mujoco"].specifier
    assert "4.0.1" not in by_name["mujoco"].specifier
    assert extras_providing("mujoco") == ("mujoco",)


def test_the_core_install_runs_adc_without_any_extra():
    blocked = non_core_modules()
    # The heavy packages of the issue are among those the core install goes without.
    assert {"pybullet", "highway_env", "rliable", "optuna", "rl_zoo3", "ray"} <= set(blocked)
    script = textwrap.dedent(
        f"""
        import json, sys
        for name in {blocked!r}:
            sys.modules[name] = None  # "import name" raises ModuleNotFoundError
        import gymnasium as gym
        import sb3_adc
        from sb3_adc import ADC

        model = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[8], n_intervals=4), learning_starts=20,
                    batch_size=8, seed=0)
        model.learn(60)
        env = gym.make("sb3_adc/NoisyPendulum-v1")
        env.reset(seed=0)
        from sb3_adc.cli import main
        status = main(["--help"])
        print(json.dumps({{"timesteps": model.num_timesteps, "status": status}}))
        """
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout.splitlines()[-1]) == {"timesteps": 60, "status": 2}
    # Without the experiment extra, `sb3-adc` says what to install instead of a traceback.
    assert 'pip install "sb3-adc[experiment]"' in result.stderr
    assert "Traceback" not in result.stderr


def test_a_missing_package_names_its_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "pybullet", None)
    with pytest.raises(MissingExtraError) as error:
        import_optional("pybullet", "envs", "the lidar course")
    assert isinstance(error.value, ModuleNotFoundError)
    assert error.value.name == "pybullet"
    assert error.value.extra == "envs"
    assert "needed by the lidar course" in str(error.value)
    assert 'pip install "sb3-adc[envs]"' in str(error.value)


def test_a_package_of_two_extras_names_the_one_asked_for(monkeypatch):
    assert extras_providing("scipy.stats") == ("envs", "experiment")
    for name in ("scipy", "scipy.stats"):
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(MissingExtraError, match=re.escape('pip install "sb3-adc[experiment]"')), requires_extra("experiment"):
        from scipy.stats import trim_mean  # noqa: F401
    with pytest.raises(MissingExtraError, match=re.escape('pip install "sb3-adc[envs]"')), requires_extra("envs"):
        import scipy  # noqa: F401


def test_a_missing_module_of_no_extra_stays_a_plain_error():
    with pytest.raises(ModuleNotFoundError) as error, requires_extra("experiment"):
        import sb3_adc_no_such_module  # noqa: F401
    assert not isinstance(error.value, MissingExtraError)
    assert missing_extra(error.value) is None


def test_an_unknown_extra_is_rejected_with_the_accepted_names():
    with pytest.raises(ValueError, match=r"extra must be one of envs, experiment, .*'plots'"):
        import_optional("numpy", "plots")


def test_sb3_adc_plot_without_rliable_says_which_extra(monkeypatch, tmp_path, capsys):
    from sb3_adc.cli import main

    csv = tmp_path / "evaluations.csv"
    csv.write_text("algo,env,seed,timesteps,mean_return\nadc,Pendulum-v1,0,100,-1000.0\n")
    cached = ("rliable", "sb3_adc.experiment.plots", "sb3_adc.experiment.statistics")
    for name in [name for name in sys.modules if name.startswith(cached)]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "rliable", None)
    assert main(["plot", "--csv", str(csv)]) == 2
    stderr = capsys.readouterr().err
    assert "sb3-adc plot: error: the package 'rliable' (needed by the benchmark " in stderr
    assert 'pip install "sb3-adc[experiment]"' in stderr
    assert not (tmp_path / "plots").exists()


def test_the_extras_helper_imports_without_torch():
    # So that the environments (which must not import torch) can guard their simulators' imports with it.
    script = (
        "import sys, sb3_adc, sb3_adc.extras; "
        "heavy = [name for name in ('torch', 'stable_baselines3') if name in sys.modules]; "
        "from sb3_adc import ADC; "
        "print(heavy, ADC.__module__)"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["[]", "sb3_adc.adc.adc"]
