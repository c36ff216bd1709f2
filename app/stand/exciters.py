"""A simulated exciter's own budget terms (issue 32 point 5): the stand file's
[exciters.<name>] with its [[exciters.<name>.component]] entries. On that exciter (the
simulated stand's catalogue names it, `--exciter`) they replace the stand's components of the
kinds they state: a long-stroke exciter has its own rocking mode, guidance errors and the
reference's low-frequency terms, not the small exciter's terms growing above 2 kHz."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

from dsp.uncertainty import Budget

if TYPE_CHECKING:
    from app.stand.config import StandConfig


def parse_exciters(data: dict[str, Any], simulated: bool) -> dict[str, Budget]:
    """The stand file's [exciters] (`data`: the whole file) by exciter name; ValueError
    "<where>: <why>" naming exciters.<name>... on bad input, and on a stand that is not the
    simulated one (`simulated`)."""
    table = data.get("exciters", {})
    if not isinstance(table, dict):
        raise ValueError("exciters: must be a table of exciter names")
    if table and not simulated:
        raise ValueError("exciters: only for the simulated stand (daq.backend = 'sim')")
    out = {}
    for name, entry in table.items():
        where = f"exciters.{name}"
        if not isinstance(entry, dict) or set(entry) - {"component"}:
            raise ValueError(f"{where}: holds only [[component]] entries")
        try:
            out[name] = Budget.from_list(entry.get("component", []))
        except ValueError as exc:
            raise ValueError(f"{where}.component: {exc}") from None
        if not out[name].components:
            raise ValueError(f"{where}: states no component")
    return out


def with_exciter_budget(config: StandConfig, exciter: str) -> StandConfig:
    """`config` with its budget on the exciter `exciter`: each component of a kind the
    exciter's entries state replaced by those entries; `config` itself when it states none
    for that exciter."""
    own = config.exciter_components.get(exciter)
    if own is None:
        return config
    kinds = {k for c in own.components for k in c.kind}
    kept = [c for c in config.budget.components if not kinds.intersection(c.kind)]
    return replace(config, budget=Budget((*kept, *own.components)))
