"""Acceptance criteria: what a reviewer signs against, each checked on the steps' results.

A criteria file (TOML) lists ``[[criterion]]`` tables:

    [[criterion]]
    name = "largest frequency error of the calibration"
    result = "calibration"        # the step's result: identification, calibration, validation, ...
    value = "max_error_pct"       # a path in it; "*" stands for every entry of a table or list
    at_most = 3.0                 # and/or at_least = ...; or one_of = ["none"] for a word
    unit = "%"
    kind = "in_service"           # optional: judged on this kind of campaign only (or stationary_excitation)

A criterion passes when every value its path reaches meets it; it is not evaluated when its
step did not run or its path reaches nothing (a campaign without floor sensors has no
measured comfort). Without a file the :data:`DEFAULTS` apply (docs/cli.md lists them).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from calibration.data.errors import InputError
from calibration.data.metadata import load_toml

from .build import RESULTS


@dataclass(frozen=True)
class Criterion:
    name: str
    result: str
    value: str
    at_most: float | None = None
    at_least: float | None = None
    one_of: tuple | None = None
    unit: str = ""
    kind: str | None = None  # the campaign kind it applies to; None: every kind

    def limit(self) -> str:
        if self.one_of is not None:
            return "one of " + ", ".join(map(str, self.one_of))
        parts = ([f">= {self.at_least:g}"] if self.at_least is not None else []) + \
                ([f"<= {self.at_most:g}"] if self.at_most is not None else [])
        return " and ".join(parts) + (f" {self.unit}" if self.unit else "")

    def meets(self, x) -> bool:
        if self.one_of is not None:
            return x in self.one_of
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            return False
        return (self.at_most is None or x <= self.at_most) and (self.at_least is None or x >= self.at_least)


KINDS = ("in_service", "stationary_excitation")

#: railcal's defaults, a starting point for a project's own file: the identified modes'
#: calibration within 3 %; in service, the simulated responses within 50 % rms and 3 dB of
#: the measured ones over the track and the model's floor comfort within 20 % of the
#: measured; on an excitation test, every floor FRF's shape (FRAC) at least 0.9 and its
#: log-magnitude within 3 dB rms; the same of the diagnosis's extended model; the diagnosis
#: finding nothing left to explain in the calibrated model, both FMUs passing their checks,
#: and exudyn agreeing with both models.
DEFAULTS = (
    Criterion("largest frequency error of the calibration", "calibration", "max_error_pct", at_most=3.0, unit="%"),
    Criterion("NRMSE of every validated channel", "validation", "channels/*/nrmse", at_most=0.5, kind="in_service"),
    Criterion("PSD error of every validated channel", "validation", "channels/*/psd_log_error_db", at_most=3.0,
              unit="dB", kind="in_service"),
    Criterion("floor comfort, model over measured N_MV,z", "validation", "ride_comfort/*/model_over_measured",
              at_least=0.8, at_most=1.2, kind="in_service"),
    Criterion("FRAC of every floor FRF", "validation", "channels/*/frac", at_least=0.9, kind="stationary_excitation"),
    Criterion("log-magnitude error of every floor FRF", "validation", "channels/*/log_error_db", at_most=3.0,
              unit="dB rms", kind="stationary_excitation"),
    Criterion("NRMSE of every validated channel, extended model", "validation_extended", "channels/*/nrmse",
              at_most=0.5, kind="in_service"),
    Criterion("PSD error of every validated channel, extended model", "validation_extended",
              "channels/*/psd_log_error_db", at_most=3.0, unit="dB", kind="in_service"),
    Criterion("FRAC of every floor FRF, extended model", "validation_extended", "channels/*/frac", at_least=0.9,
              kind="stationary_excitation"),
    Criterion("log-magnitude error of every floor FRF, extended model", "validation_extended",
              "channels/*/log_error_db", at_most=3.0, unit="dB rms", kind="stationary_excitation"),
    Criterion("diagnosis: nothing systematic left unexplained", "diagnosis", "cause", one_of=("none",)),
    Criterion("FMU checks of the calibrated model", "fmu_baseline", "verdict", one_of=("pass",)),
    Criterion("FMU checks of the extended model", "fmu_extended", "verdict", one_of=("pass",)),
    Criterion("exudyn cross-check of the calibrated model", "crosscheck", "verdict", one_of=("pass",)),
    Criterion("exudyn cross-check of the extended model", "crosscheck_extended", "verdict", one_of=("pass",)),
)


def load_criteria(path) -> tuple[Criterion, ...]:
    """The criteria of a TOML file; a malformed one is refused naming the file and key."""
    path = Path(path)
    data = load_toml(path, root=None)
    rows = data.get("criterion")
    if not isinstance(rows, list) or not rows:
        raise InputError("no [[criterion]] table", path=path, key="criterion")
    out = []
    for i, row in enumerate(rows):
        key = f"criterion[{i}]"
        if not isinstance(row, dict):
            raise InputError("expected a table", path=path, key=key)
        unknown = set(row) - {"name", "result", "value", "at_most", "at_least", "one_of", "unit", "kind"}
        if unknown:
            raise InputError(f"unknown key(s) {', '.join(sorted(unknown))}", path=path, key=key)
        for k in ("name", "result", "value"):
            if not isinstance(row.get(k), str) or not row[k]:
                raise InputError(f"needs {k} (text)", path=path, key=f"{key}.{k}")
        if row["result"] not in RESULTS:
            raise InputError(f"result must be one of {', '.join(RESULTS)}, got {row['result']!r}", path=path,
                             key=f"{key}.result")
        for k in ("at_most", "at_least"):
            v = row.get(k)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)):
                raise InputError(f"must be a finite number, got {v!r}", path=path, key=f"{key}.{k}")
        one_of = row.get("one_of")
        if one_of is not None and (not isinstance(one_of, list) or not one_of):
            raise InputError("must be a non-empty list", path=path, key=f"{key}.one_of")
        if one_of is None and row.get("at_most") is None and row.get("at_least") is None:
            raise InputError("needs at_most, at_least or one_of", path=path, key=key)
        if one_of is not None and (row.get("at_most") is not None or row.get("at_least") is not None):
            raise InputError("one_of goes alone, without at_most or at_least", path=path, key=key)
        if row.get("kind") is not None and row["kind"] not in KINDS:
            raise InputError(f"kind must be one of {', '.join(KINDS)}, got {row['kind']!r}", path=path,
                             key=f"{key}.kind")
        lo, hi = row.get("at_least"), row.get("at_most")
        if lo is not None and hi is not None and lo > hi:
            raise InputError(f"at_least {lo} is above at_most {hi}: nothing can pass", path=path, key=key)
        out.append(Criterion(row["name"], row["result"], row["value"], hi, lo,
                             None if one_of is None else tuple(one_of), str(row.get("unit", "")), row.get("kind")))
    return tuple(out)


def values_at(obj, path: str) -> list[tuple[str, object]]:
    """(concrete path, value) of every value ``path`` reaches in ``obj`` ("*": each entry)."""
    found = [("", obj)]
    for part in path.split("/"):
        nxt = []
        for where, x in found:
            if part == "*":
                items = x.items() if isinstance(x, dict) else enumerate(x) if isinstance(x, list) else ()
                nxt += [(f"{where}/{k}", v) for k, v in items]
            elif isinstance(x, dict) and part in x:
                nxt.append((f"{where}/{part}", x[part]))
            elif isinstance(x, list) and part.isdigit() and int(part) < len(x):
                nxt.append((f"{where}/{part}", x[int(part)]))
        found = nxt
    return [(where.lstrip("/"), x) for where, x in found if x is not None]


def with_derived(results: dict) -> dict:
    """``results`` with the ratios the defaults read: each floor position's model over
    measured N_MV,z (where a floor accelerometer measured it)."""
    val = results.get("validation")
    if not isinstance(val, dict) or not isinstance(val.get("ride_comfort"), dict):
        return results
    comfort = {}
    for pos, c in val["ride_comfort"].items():
        c = dict(c)
        m = c.get("measured") or {}
        if m.get("n_mv_z"):
            c["model_over_measured"] = c["model"]["n_mv_z"] / m["n_mv_z"]
        comfort[pos] = c
    return {**results, "validation": {**val, "ride_comfort": comfort}}


def campaign_kind(results: dict) -> str | None:
    """The kind of campaign (:data:`KINDS`) the results were made from, when one of them says."""
    return next((r["kind"] for r in results.values() if isinstance(r, dict) and r.get("kind") in KINDS), None)


def evaluate(criteria, results: dict, not_applicable: dict | None = None) -> list[dict]:
    """Each criterion's row: name, limit, the values it read (path, value, pass, and whether
    it is derived from the results rather than in them), its status (``pass``, ``fail``,
    ``not evaluated`` or ``not applicable``) and why when it is not judged. A criterion for
    another kind of campaign than the results' has no row; one on a result in
    ``not_applicable`` ({result: why}: a step the campaign's answers made needless, such as
    the extended model's when the diagnosis found nothing) is not applicable."""
    raw, results = results, with_derived(results)
    kind = campaign_kind(results)
    rows = []
    for c in criteria:
        if c.kind is not None and kind is not None and c.kind != kind:
            continue
        row = {"name": c.name, "result": c.result, "value": c.value, "limit": c.limit(), "values": []}
        if c.result not in results and c.result in (not_applicable or {}):
            rows.append({**row, "status": "not applicable", "why": not_applicable[c.result]})
            continue
        if c.result not in results:
            rows.append({**row, "status": "not evaluated", "why": f"no {c.result} result"})
            continue
        found = values_at(results[c.result], c.value)
        if not found:
            rows.append({**row, "status": "not evaluated", "why": f"nothing at {c.value}"})
            continue
        vals = [{"path": f"{c.result}/{where}", "value": x, "pass": c.meets(x),
                 "derived": not values_at(raw[c.result], where)} for where, x in found]
        rows.append({**row, "values": vals, "status": "pass" if all(v["pass"] for v in vals) else "fail"})
    return rows


def verdict(rows) -> str:
    """The report's summary verdict from the criteria's rows."""
    idle = [r["name"] for r in rows if r["status"] == "not applicable"]
    rows = [r for r in rows if r["status"] != "not applicable"]
    failed = [r["name"] for r in rows if r["status"] == "fail"]
    open_ = [r["name"] for r in rows if r["status"] == "not evaluated"]
    aside = f" {len(idle)} not applicable ({'; '.join(idle)})." if idle else ""
    if failed:
        return f"Not accepted: {len(failed)} of {len(rows)} criteria failed ({'; '.join(failed)}).{aside}"
    if open_:
        return (f"Accepted on the {len(rows) - len(open_)} criteria evaluated; {len(open_)} not evaluated "
                f"({'; '.join(open_)}).{aside}")
    return f"Accepted: all {len(rows)} criteria met.{aside}"
