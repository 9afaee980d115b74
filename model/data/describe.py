"""Text descriptions of articulated objects at four lengths (DESIGN §3.1), from ground truth.

``describe(obj, rng)`` returns ``{length: [variants...]}`` for the lengths of
``model.data.format.DESCRIPTION_LENGTHS``: "detailed" (a paragraph with sizes, sides and
ranges), "sentences" (two or three sentences), "sentence" (one), "words" (a few words).
Every variant names the category and, for every countable part kind, its count and how it
moves, with wording drawn from the synonym tables in :mod:`model.data.vocab` — so a parser
that knows those tables reads back :func:`structured_summary`.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from model.core.objects import ArticulatedObject, JointType
from model.data import vocab
from model.data.format import DESCRIPTION_LENGTHS

VARIANTS_PER_LENGTH = 3

# Which parts a viewer reads first.
_ORDER = ("drawer", "door", "lid", "cap", "tray", "knob", "dial", "button", "handle", "other")


def structured_summary(obj: ArticulatedObject) -> dict:
    """``ArticulatedObject.summary()`` (category, counts, joint_types, num_parts, num_movable)."""
    return obj.summary()


def _count(rng, n: int) -> str:
    if n == 1:
        return _choice(rng, ["a", "one", "a single"])
    return _choice(rng, [vocab.number_word(n), vocab.number_word(n), str(n)])


def _choice(rng, items):
    return items[int(rng.integers(len(items)))]


def _noun(rng, label: str, n: int, canonical_share: float = 0.5) -> str:
    """Singular or plural synonym of a part label (canonical wording half of the time)."""
    table = vocab.PART_SYNONYMS[label] if n == 1 else vocab.PART_PLURALS[label]
    if rng.random() < canonical_share:
        return table[0]
    return _choice(rng, list(table))


def _category_noun(rng, obj: ArticulatedObject, counts: dict) -> str:
    cat = obj.category
    if cat == "StorageFurniture":
        opts = ["cabinet", "storage cabinet", "cupboard", "storage unit", "sideboard"]
        if counts.get("drawer") and not counts.get("door"):
            opts += ["chest of drawers", "dresser", "chest"]
        return _choice(rng, opts)
    if cat == "WashingMachine":
        opts = ["washing machine", "washer", "laundry machine", "clothes washer"]
        loading = obj.metadata.get("loading")
        if loading == "front":
            opts += ["front-loader", "front-loading washer"]
        elif loading == "top":
            opts += ["top-loader", "top-loading washer"]
        return _choice(rng, opts)
    if cat == "Bottle":
        return _choice(rng, ["bottle", "flask", "water bottle", "drink bottle"])
    return _choice(rng, list(vocab.CATEGORY_SYNONYMS.get(cat, (cat.lower(),))))


def _article(noun: str) -> str:
    return "an" if noun[:1] in "aeiou" and not noun.startswith(("usb", "one", "uni")) else "a"


def _groups(obj: ArticulatedObject) -> list[tuple[str, int, list[str], list[int]]]:
    """(label, count, sorted joint type names, part indices) per countable label, fixed order."""
    out = []
    for label in _ORDER:
        idx = [i for i, p in enumerate(obj.parts) if p.label == label]
        if idx and label in vocab.COUNTABLE_LABELS:
            types = sorted({obj.parts[i].joint.type.name.lower() for i in idx})
            out.append((label, len(idx), types, idx))
    return out


def _motion(rng, label: str, types: list[str], n: int) -> str:
    """Verb phrase for a group ('slide out', 'swing open', 'stay fixed'), plural when n > 1."""
    if types == ["fixed"]:
        return _choice(rng, ["are fixed", "are rigidly attached", "do not move"]) if n > 1 else \
            _choice(rng, ["is fixed", "is rigidly attached", "does not move"])
    kinds = [t for t in types if t != "fixed"]
    if len(kinds) > 1:
        names = " or ".join(_motion_word(rng, k, label) for k in kinds)
        return ("can " if n > 1 else "can ") + names
    table = vocab.LABEL_MOTION_SYNONYMS.get((label, kinds[0]), vocab.MOTION_SYNONYMS[kinds[0]])
    phrase = _choice(rng, [p for p in table if p != "is hinged"] or list(table))
    return _pluralise_verb(phrase) if n > 1 else phrase


def _motion_word(rng, jt: str, label: str = "") -> str:
    if jt == "revolute" and label in ("knob", "dial"):
        return _choice(rng, ["turn to a stop", "turn within a range"])
    return {"revolute": _choice(rng, ["swing on a hinge", "pivot", "rotate on a hinge"]),
            "prismatic": _choice(rng, ["slide", "slide in and out", "translate"]),
            "continuous": _choice(rng, ["spin freely", "turn without limit", "rotate continuously"]),
            "screw": _choice(rng, ["screw on and off", "twist off"])}[jt]


_VERB_PLURAL = {"is": "are", "slides": "slide", "pulls": "pull", "moves": "move", "translates": "translate",
                "swings": "swing", "rotates": "rotate", "pivots": "pivot", "opens": "open", "spins": "spin",
                "turns": "turn", "screws": "screw", "twists": "twist", "unscrews": "unscrew",
                "does": "do", "can": "can", "presses": "press", "pushes": "push", "swivels": "swivel"}


def _pluralise_verb(phrase: str) -> str:
    first, _, rest = phrase.partition(" ")
    first = _VERB_PLURAL.get(first, first)
    return f"{first} {rest}".strip()


def _group_np(rng, label: str, n: int, types: list[str]) -> str:
    """'three sliding drawers' / 'a hinged door' / 'two knobs'."""
    noun = _noun(rng, label, n)
    adj = ""
    moving = [t for t in types if t != "fixed"]
    if len(moving) == 1 and rng.random() < 0.5 and not any(w in noun for w in ("sliding", "hinged", "pull-out", "flip", "rotary")):
        adj = _choice(rng, list(vocab.LABEL_MOTION_ADJECTIVES.get((label, moving[0]),
                                                                  vocab.MOTION_ADJECTIVES[moving[0]])))
        # no "push push-buttons" / "swinging swing doors"
        adj = "" if adj[:4] in noun or any(w[:4] in adj for w in noun.split()) else adj + " "
    return f"{_count(rng, n)} {adj}{noun}"


def _sides(obj: ArticulatedObject, idx: list[int]) -> list[str]:
    parts_meta = obj.metadata.get("parts", {})
    return [parts_meta.get(obj.parts[i].name, {}).get("side", "") for i in idx]


def _side_clause(rng, label: str, obj: ArticulatedObject, idx: list[int]) -> str:
    sides = [s for s in _sides(obj, idx) if s]
    if not sides or label not in ("door", "lid"):
        return ""
    uniq = sorted(set(sides))
    if len(uniq) == 1:
        s = uniq[0]
        if s == "back":
            return _choice(rng, [" hinged at the back", " with a rear hinge"])
        return _choice(rng, [f" hinged on the {s}", f" with a {s} hinge", f" hinged at the {s}"])
    return " hinged on the " + " and ".join(uniq) + " sides" if all(s in ("left", "right") for s in uniq) \
        else " hinged on different sides"


def _range_clause(obj: ArticulatedObject, idx: list[int]) -> str:
    js = [obj.parts[i].joint for i in idx]
    jt = js[0].type
    if jt == JointType.PRISMATIC:
        hi = max(j.t_range[1] - j.t_range[0] for j in js)
        return f"by up to {hi * 100:.0f} cm" if hi >= 0.01 else f"by {hi * 1000:.0f} mm"
    if jt == JointType.REVOLUTE:
        hi = max(j.r_range[1] - j.r_range[0] for j in js)
        return f"through up to {math.degrees(hi):.0f} degrees"
    if jt == JointType.SCREW:
        turns = js[0].r_range[1] / (2 * math.pi)
        return f"over {turns:.1f} turns while lifting {js[0].t_range[1] * 1000:.0f} mm"
    return ""


def _join(items: list[str]) -> str:
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def _size_phrase(rng, obj: ArticulatedObject) -> str:
    size = obj.metadata.get("size")
    if not size:
        return ""
    d, w, h = size
    if max(size) < 0.3:
        return f"about {h * 100:.0f} cm tall" if obj.category == "Bottle" else f"about {max(size) * 100:.0f} cm long"
    return _choice(rng, [f"{w:.2f} m wide, {d:.2f} m deep and {h:.2f} m tall",
                         f"about {w * 100:.0f} cm wide and {h * 100:.0f} cm high"])


def _facts(rng, obj, groups) -> list[str]:
    """One clause per group: 'three drawers that slide out'."""
    out = []
    for label, n, types, idx in groups:
        np_ = _group_np(rng, label, n, types)
        out.append(f"{np_}{_side_clause(rng, label, obj, idx)} that {_motion(rng, label, types, n)}")
    return out


def _cap_first(s: str) -> str:
    return s[:1].upper() + s[1:]


def describe(obj: ArticulatedObject, rng: Optional[np.random.Generator] = None,
             variants: int = VARIANTS_PER_LENGTH) -> dict[str, list[str]]:
    """Descriptions per length (``variants`` each), deterministic for a given ``rng``."""
    rng = rng if rng is not None else np.random.default_rng(0)
    summ = obj.summary()
    counts = summ["counts"]
    groups = _groups(obj)
    out: dict[str, list[str]] = {k: [] for k in DESCRIPTION_LENGTHS}
    for _ in range(variants):
        cat = _category_noun(rng, obj, counts)
        facts = _facts(rng, obj, groups)
        nps = [_group_np(rng, label, n, types) for label, n, types, _ in groups]
        # -- words: "cabinet, 3 drawers, 2 doors" -----------------------------------------
        style = int(rng.integers(3))
        words_nps = [f"{n if style != 1 else vocab.number_word(n)} {_noun(rng, l, n, 0.7)}" for l, n, _, _ in groups]
        if style == 2:
            words = f"{cat} with " + _join(words_nps) if words_nps else cat
        else:
            words = ", ".join([cat] + words_nps)
        out["words"].append(words)
        # -- sentence --------------------------------------------------------------------
        opener = _choice(rng, ["A {c} with {f}.", "This is {a} {c} with {f}.", "{A} {c} that has {f}.",
                               "{A} {c} featuring {f}."])
        a = _article(cat)
        sent = opener.format(c=cat, f=_join(facts) if facts else "no moving parts", a=a, A=_cap_first(a))
        out["sentence"].append(_cap_first(sent))
        # -- sentences -------------------------------------------------------------------
        s1 = _choice(rng, [f"{_cap_first(_article(cat))} {cat}.", f"The object is {_article(cat)} {cat}.",
                           f"This is {_article(cat)} {cat}."])
        if groups:
            s2 = _choice(rng, [f"It has {_join(nps)}.", f"It comes with {_join(nps)}.",
                               f"On it there are {_join(nps)}."])
            motions = []
            for label, n, types, idx in groups:
                noun = _noun(rng, label, n)
                the = "The" if n > 1 else "The"
                motions.append(f"{the} {noun} {_motion(rng, label, types, n)}")
            s3 = _join(motions[:1] + [m[0].lower() + m[1:] for m in motions[1:]]) + "."
            sentences = " ".join([s1, s2, s3])
        else:
            sentences = s1 + " " + _choice(rng, ["It has no moving parts.", "Nothing on it moves."])
        out["sentences"].append(sentences)
        # -- detailed --------------------------------------------------------------------
        size = _size_phrase(rng, obj)
        lines = [f"{_cap_first(_article(cat))} {cat}" + (f", {size}" if size else "") + "."]
        total = summ["num_movable"]
        lines.append(_choice(rng, [f"It has {total} moving part{'s' if total != 1 else ''} in total.",
                                   f"Altogether {total} of its parts can move.",
                                   f"In total {total} part{'s' if total != 1 else ''} move."]))
        for (label, n, types, idx), fact in zip(groups, facts):
            rng_txt = _range_clause(obj, idx)
            extra = ""
            styles = {obj.metadata.get("parts", {}).get(obj.parts[i].name, {}).get("style", "") for i in idx}
            styles.discard("")
            if label == "handle" and styles:
                extra = f" ({_join(sorted(styles))} style)"
            lines.append(_cap_first(f"there {'is' if n == 1 else 'are'} {fact}{extra}"
                                    + (f", {rng_txt}" if rng_txt else "") + "."))
        out["detailed"].append(" ".join(lines))
    return out
