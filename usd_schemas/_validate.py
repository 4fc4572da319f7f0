"""Validation of written USD packages: composition, usd-core's validators, omniverse-asset-validator.

Three sources, one report:

- ``composition``: errors USD reports while composing the stage (missing payload, bad paths);
- ``usd``: every validator registered in usd-core's ``UsdValidation`` registry (usd-core 26.11:
  30 validators over stage metadata, composition, encapsulation, material bindings, shader
  compliance, normal maps, physics joints/colliders/rigid bodies/articulations, skel, media, ...);
- ``omni``: ``omni.asset_validator.ValidationEngine`` with its default rules. Severity ERROR and
  FAILURE count as errors. No rule is disabled (``DISABLED_OMNI_RULES`` is empty; a rule may be
  listed there only with the reason it does not apply to asset packages).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict

log = logging.getLogger(__name__)

Severity = Literal["error", "warning", "info"]

# rule class name -> why it does not apply to AgentWorld asset packages
DISABLED_OMNI_RULES: dict[str, str] = {}


class ValidationIssue(BaseModel):
    """One finding. source: composition | usd | omni; rule: validator or rule name; at: where."""

    model_config = ConfigDict(frozen=True)

    source: Literal["composition", "usd", "omni"]
    rule: str
    severity: Severity
    message: str
    at: str = ""

    def line(self) -> str:
        at = f" at {self.at}" if self.at else ""
        return f"[{self.severity}] {self.source}:{self.rule}{at}: {self.message}"


class ValidationReport(BaseModel):
    """All findings for the package whose root layer is ``path``."""

    model_config = ConfigDict(frozen=True)

    path: Path
    issues: tuple[ValidationIssue, ...]
    disabled_rules: tuple[str, ...] = ()

    @property
    def errors(self) -> tuple[ValidationIssue, ...]:
        return tuple(i for i in self.issues if i.severity == "error")

    @property
    def warnings(self) -> tuple[ValidationIssue, ...]:
        return tuple(i for i in self.issues if i.severity == "warning")

    @property
    def ok(self) -> bool:
        """True when there is no error (warnings and infos allowed)."""
        return not self.errors

    def summary(self) -> str:
        """One line: the path and the error count, then the first errors."""
        errs = self.errors
        head = f"{self.path}: {len(errs)} validation error(s), {len(self.warnings)} warning(s)"
        return head if not errs else head + ": " + "; ".join(i.line() for i in errs[:5])


def validate_package(path: Path) -> ValidationReport:
    """Validate the USD file ``path`` (an asset package's root layer) with all three sources."""
    from usd_schemas._registry import register

    register()
    path = Path(path)
    if not path.is_file():
        return ValidationReport(path=path, issues=(ValidationIssue(
            source="composition", rule="open", severity="error", message="file not found"),))
    issues: list[ValidationIssue] = []
    stage = _open(path, issues)
    if stage is not None:
        issues += _composition_issues(stage)
        issues += _usd_validator_issues(stage)
    issues += _omni_issues(path)
    return ValidationReport(path=path, issues=tuple(issues), disabled_rules=tuple(sorted(DISABLED_OMNI_RULES)))


def _open(path: Path, issues: list[ValidationIssue]):
    from pxr import Tf, Usd

    try:
        return Usd.Stage.Open(str(path), Usd.Stage.LoadAll)
    except Tf.ErrorException as e:
        issues.append(ValidationIssue(source="composition", rule="open", severity="error",
                                      message=" ".join(str(e).split())))
        return None


def _composition_issues(stage) -> list[ValidationIssue]:
    return [ValidationIssue(source="composition", rule=type(err).__name__, severity="error",
                            message=" ".join(str(err).split()))
            for err in stage.GetCompositionErrors()]


def _usd_validator_issues(stage, validators=None) -> list[ValidationIssue]:
    """Issues of usd-core's validators (``validators``: a list of them; None: all registered)."""
    from pxr import UsdValidation

    if validators is None:
        validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    ctx = UsdValidation.ValidationContext(validators)
    sev = {UsdValidation.ValidationErrorType.Error: "error", UsdValidation.ValidationErrorType.Warn: "warning",
           UsdValidation.ValidationErrorType.Info: "info"}
    out = []
    for err in ctx.Validate(stage):
        if err.HasNoError():
            continue
        v = err.GetValidator()
        name = v.GetMetadata().name if v else err.GetName()
        sites = [str(s.GetPrim().GetPath()) if s.IsPrim() else (str(s.GetProperty().GetPath()) if s.IsProperty()
                 else (s.GetLayer().identifier if s.GetLayer() else "")) for s in err.GetSites()]
        out.append(ValidationIssue(source="usd", rule=str(name), severity=sev.get(err.GetType(), "error"),
                                   message=" ".join(err.GetMessage().split()), at=", ".join(x for x in sites if x)))
    return out


def _omni_issues(path: Path) -> list[ValidationIssue]:
    from omni.asset_validator import IssueSeverity, ValidationEngine

    engine = ValidationEngine(init_rules=True)
    for rule in list(engine.enabled_rules):
        if rule.__name__ in DISABLED_OMNI_RULES:
            engine.disable_rule(rule)
    sev = {IssueSeverity.ERROR: "error", IssueSeverity.FAILURE: "error", IssueSeverity.WARNING: "warning",
           IssueSeverity.INFO: "info"}
    out = []
    for issue in engine.validate(str(path)).issues():
        if issue.severity == IssueSeverity.NONE:
            continue
        rule = issue.rule.__name__ if issue.rule is not None else "engine"
        at = "" if issue.at is None else str(getattr(issue.at, "path", None) or issue.at)
        out.append(ValidationIssue(source="omni", rule=rule, severity=sev.get(issue.severity, "error"),
                                   message=" ".join(str(issue.message).split()), at=at))
    return out
