"""The command line takes AnalyzerConfig's defaults: ``analyze`` and Python cannot differ."""

from __future__ import annotations

import argparse
import dataclasses

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.cli import analyze
from energy_margin.errors import Constraint, field_constraint


def analyze_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser()
    analyze.add_arguments(parser)
    return parser


def test_every_analyzer_option_defaults_to_the_dataclass_default() -> None:
    parser = analyze_parser()
    dests = {action.dest for action in parser._actions}
    exposed = [field for field in dataclasses.fields(AnalyzerConfig) if field.name in dests]
    assert len(exposed) >= 12, [field.name for field in exposed]
    for field in exposed:
        if field.name == "expansions":
            # Absent, --expansions is the dataclass default unless --nodes alone sets the budget.
            assert parser.get_default("expansions") is None and field.default == analyze.DEFAULT_EXPANSIONS
            continue
        assert parser.get_default(field.name) == field.default, field.name


def test_analyze_without_options_builds_the_default_configuration() -> None:
    args = analyze_parser().parse_args(["data"])
    assert analyze.analyzer_config(args) == AnalyzerConfig()


def test_every_analyzer_field_declares_its_constraint() -> None:
    for field in dataclasses.fields(AnalyzerConfig):
        constraint = field_constraint(AnalyzerConfig, field.name)
        assert isinstance(constraint, Constraint), field.name
        assert constraint.check(field.name, field.default) == field.default or constraint.kind == "float"


def test_sweep_and_budget_take_the_analyzer_defaults_too() -> None:
    from energy_margin.cli import budget, sweep

    for command in (sweep, budget):
        parser = argparse.ArgumentParser()
        command.add_arguments(parser)
        dests = {action.dest for action in parser._actions}
        shared = [field for field in dataclasses.fields(AnalyzerConfig) if field.name in dests]
        assert shared, command.NAME
        for field in shared:
            default = parser.get_default(field.name)
            if command is budget and field.name == "expansions":
                # budget compares several budgets: a list of expansions per frame, the analyzer's among them.
                assert field.default in default
                continue
            assert default == field.default, (command.NAME, field.name)


def test_control_takes_the_controller_defaults() -> None:
    from energy_margin.cli import control
    from energy_margin.control.mppi import ControllerConfig

    parser = argparse.ArgumentParser()
    control.add_arguments(parser)
    dests = {action.dest for action in parser._actions}
    shared = [field for field in dataclasses.fields(ControllerConfig) if field.name in dests]
    assert len(shared) >= 6
    for field in shared:
        assert parser.get_default(field.name) == field.default, field.name
    for field in dataclasses.fields(ControllerConfig):
        assert isinstance(field_constraint(ControllerConfig, field.name), Constraint), field.name


def test_learn_fits_the_same_kind_by_default_in_python_and_on_the_command_line() -> None:
    import inspect

    from energy_margin.cli import learn
    from energy_margin.learning.margin_model import DEFAULT_KIND, fit_margin_model
    from energy_margin.learning.pipeline import learn_pipeline

    parser = argparse.ArgumentParser()
    learn.add_arguments(parser)
    assert parser.get_default("kind") == DEFAULT_KIND
    assert inspect.signature(fit_margin_model).parameters["kind"].default == DEFAULT_KIND
    assert inspect.signature(learn_pipeline).parameters["kind"].default == DEFAULT_KIND
