"""The kinds of map compared: where their loops agree on the physics, where they differ, and
which finding to trust.

The workflow runs the same loop on grid, neural-network and Gaussian-process maps. Each kind's
maps err in their own way, and a loop adds what makes up for its maps' error beside what the
valve holds. So the effects the loops added are grouped by the physics they stand for
(:func:`~surrogate.reporting.naming.family`: a friction of free shape rising with viscosity and
the library's friction growing with viscosity are one family), and for each family:

* added on **every** kind of map: the common physics, to trust; where the kinds chose different
  terms for it, the shape of the kind whose final model predicts the runs left out best, and
  where those terms differ in category (valve physics on one kind, a correction of the maps on
  another) the log holds it but does not say what it is;
* added on **some** kinds only: to trust provisionally if the kind that predicts the runs left
  out best is among them, else most likely those kinds' own map error.

"Predicts the runs left out best": the lowest RMS of the final model on runs its fit did not see
(:attr:`~surrogate.workbench.workflow.Step.heldout_check`, the same figure on every kind).
"""

from __future__ import annotations

from dataclasses import dataclass

from .display import in_bar
from .naming import Family, family
from .verdict import category_words, what


@dataclass(frozen=True)
class Term:
    """An effect a kind's loop added: its name, title (in words), category and family."""

    name: str
    words: str
    category: str
    family: Family

    @classmethod
    def of(cls, effect) -> "Term":
        return cls(effect.name, what(effect), effect.category, family(effect))


@dataclass(frozen=True)
class FamilyAcross:
    """One physical family across the kinds: the terms each kind's loop added for it
    ({kind: terms}, only the kinds that added one)."""

    family: Family
    terms: dict

    def kinds(self) -> list[str]:
        return list(self.terms)


@dataclass(frozen=True)
class KindsComparison:
    """The families the kinds' loops added, each kind's final RMS on held-out runs [Pa], and
    the kind that predicts them best."""

    families: tuple[FamilyAcross, ...]
    heldout: dict
    trusted: str
    main: str

    def to_json(self) -> dict:
        return {"trusted": self.trusted,
                "heldout_rms_bar": {kind: round(float(in_bar(value)), 4)
                                    for kind, value in self.heldout.items()},
                "families": [{"family": across.family.words,
                              "added": {kind: [term.name for term in terms]
                                        for kind, terms in across.terms.items()},
                              "verdict": family_sentence(self, across)}
                             for across in self.families]}


def diagnosed_terms(workflow) -> list[Term]:
    """The effects a workflow's diagnoses added, in order (neither the paper's steps nor the
    maps' calibration, which every kind ends with)."""
    return [Term.of(step.model.effect(name))
            for step in workflow.steps if step.diagnosis is not None for name in step.added]


def compare_kinds(workflows: dict, main: str) -> KindsComparison:
    """Group the terms every kind's loop added by family ({kind: Workflow}, ``main`` the
    report's kind), in the order the main kind, then the others, added them."""
    found: dict[Family, dict] = {}
    for kind in [main, *(k for k in workflows if k != main)]:
        for term in diagnosed_terms(workflows[kind]):
            found.setdefault(term.family, {}).setdefault(kind, []).append(term)
    heldout = {kind: workflow.final.heldout_check for kind, workflow in workflows.items()}
    trusted = min(heldout, key=lambda kind: (heldout[kind], kind != main))
    return KindsComparison(tuple(FamilyAcross(key, {kind: tuple(terms) for kind, terms
                                                    in by_kind.items()})
                                 for key, by_kind in found.items()), heldout, trusted, main)


def _maps(kinds) -> str:
    """"grid and nn maps"."""
    kinds = list(kinds)
    names = kinds[0] if len(kinds) == 1 else ", ".join(kinds[:-1]) + " and " + kinds[-1]
    return f"{names} maps"


def _by_terms(across: FamilyAcross) -> str:
    """Each choice of terms with the kinds that made it: "gp maps as a friction ...
    (valve physics; shape_friction_of_nu); grid and nn maps as ...", names last; one choice
    alone without the kinds ("as ...")."""
    choices: dict[tuple, list[str]] = {}
    for kind, terms in across.terms.items():
        choices.setdefault(terms, []).append(kind)
    if len(choices) == 1 and not across.family.variable:  # the family is the term: its title
        term = next(iter(choices))[0]
        return f"{category_words(term.category)}; {term.name}"
    return "; ".join((f"{_maps(kinds)} " if len(choices) > 1 else "") + "as " + " and ".join(
        f"{term.words} ({category_words(term.category)}; {term.name})" for term in terms)
        for terms, kinds in choices.items())


def _added(words: str, by_terms: str, family: Family) -> str:
    """"a friction growing with ν, as friction growing with viscosity (...)", or for a family
    without a variable, its title with the category and name in parentheses."""
    return f"{words} ({by_terms})" if not family.variable else f"{words}, {by_terms}"


def trust_sentence(comparison: KindsComparison) -> str:
    """Which kind's final model predicts the runs left out best, with every kind's figure."""
    figures = ", ".join(f"{kind} {in_bar(value):.3f} bar"
                        for kind, value in sorted(comparison.heldout.items(),
                                                  key=lambda item: item[1]))
    sentence = (f"The {comparison.trusted} maps' final model predicts the runs left out best "
                f"(RMS on runs its fit did not see: {figures}): where the kinds disagree, "
                f"trust its findings.")
    if comparison.trusted != comparison.main:
        sentence += (f" The report follows the {comparison.main} maps, whose flow force is "
                     "the most accurate by cross-validation; on this log the other kind "
                     "predicts better.")
    return sentence


def family_sentence(comparison: KindsComparison, across: FamilyAcross) -> str:
    """What the kinds say about one family, and what to trust of it and why."""
    every = len(across.terms) == len(comparison.heldout)
    trusted = comparison.trusted
    words = across.family.words
    if every and len({terms for terms in across.terms.values()}) == 1:
        return (f"Every kind adds {_added(words, _by_terms(across), across.family)}: the maps "
                "agree, so trust it.")
    if every:
        # the kinds that call it valve physics: all, none, or some (then they differ on what it is)
        physics = [kind for kind, terms in across.terms.items()
                   if any(term.category == "physics" for term in terms)]
        sentence = (f"Every kind adds {words}, each in its own term: {_by_terms(across)}. "
                    f"Trust the common physics, {words}")
        if 0 < len(physics) < len(across.terms):
            return sentence + (": the kinds agree the log holds it, not what it is. Take the "
                               f"{trusted} maps' term (their final model predicts the runs left "
                               "out best) until a test of the part itself, or CFD runs where "
                               "the maps are least sure, tells them apart.")
        return sentence + (f", in the shape of the {trusted} maps' term: their final model "
                           "predicts the runs left out best.")
    others = [kind for kind in comparison.heldout if kind not in across.terms]
    sentence = (f"Only {_maps(across.kinds())} add "
                f"{_added(words, _by_terms(across), across.family)}; {_maps(others)} do without.")
    if trusted in across.terms:
        return sentence + (f" Trust it provisionally: the {trusted} maps, whose final model "
                           "predicts the runs left out best, need it; the other kinds' maps may "
                           "carry it in their own error.")
    physics = any(term.category == "physics" for terms in across.terms.values()
                  for term in terms)
    return sentence + (f" The {trusted} maps, whose final model predicts the runs left out best, "
                       f"do without it: most likely it makes up for the {_maps(across.kinds())}' "
                       "own error" + (" rather than being valve physics." if physics else "."))


def comparison_sentences(comparison: KindsComparison) -> list[str]:
    """Which kind to trust, then one sentence per family the kinds' loops added."""
    return [trust_sentence(comparison),
            *(family_sentence(comparison, across) for across in comparison.families)]


__all__ = ["KindsComparison", "compare_kinds", "comparison_sentences"]
