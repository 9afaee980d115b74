"""Spatial facts of a prompt for the parser (model.metrics.prompt_parse): "hinged on the left",
"opens downward", "in two columns", "on the right", "above the door", and grid wordings that
carry a count ("two rows of three drawers" -> 6 drawers). Left / right are the viewer's
(model.data.vocab.SIDE_DIRECTIONS).

Per sentence: ``_rewrite_counts`` rewrites the grid wordings, ``_spatial_facts`` finds the
phrases (as ``_Fact`` spans), ``_attach`` merges each into the structure's ``spatial`` under
the part it describes.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from model.data import vocab

from .expected_structure import ARRANGEMENT_KEYS
from .prompt_lexicon import SIDE_ADJECTIVES, STOP_WORDS, _Tok, _tokenize

_N = r"(\d+|" + "|".join(sorted(vocab.NUMBER_WORDS[1:13], key=len, reverse=True)) + r"|a single|single)"
_SIDE = r"(left|right|top|bottom|back|rear|upper|lower|side)"
_SIDE_NAME = {"rear": "back", "upper": "top", "lower": "bottom"}
HINGED = ("door", "lid", "cap")   # a bottle's hinged "cap" is read as its lid (prompt_parse._tidy)
ARRANGED = ("drawer", "door", "lid", "tray", "knob", "dial", "button")


def _num(word: str) -> int:
    word = word.strip()
    if word.isdigit():
        return int(word)
    if word in ("a single", "single"):
        return 1
    return vocab.NUMBER_VALUES[word]


@dataclass
class _Fact:
    key: str
    values: list
    start: int
    end: int
    mode: str            # "post": the part named before; "pre": the part named next
    relation_to: str | None = None
    implied: bool = False  # not said of the part but implied ("left of the door": the door
                           # is on the right); kept only where nothing says otherwise
    panel: bool = False    # said of a control panel: about the controls named with it


def _tiers(m: re.Match) -> str:
    """"N upper [parts] and M lower parts": one row of N above one of M. As many in each
    tier is two rows of N; otherwise the parts are said in both (the part named after "lower"
    once, "two upper and one lower door", counts for both). Unchanged where the upper tier
    names another part ("two upper doors and two lower drawers")."""
    n1, said, n2, w1, w2 = m.group(1), m.group(2).strip(), m.group(3), m.group(4), m.group(5)
    if w2 and _is_part(w2):
        parts, rest = f"{w1} {w2}", ""
    elif _is_part(w1):
        parts, rest = w1, f" {w2}" if w2 else ""
    else:
        return m.group(0)
    if said and said.split()[-1].rstrip("s") != parts.split()[-1].rstrip("s"):
        return m.group(0)
    if _num(n1) == _num(n2) > 1:
        return f"two rows of {n1} {parts}{rest}"
    upper = said or (parts if parts.endswith("s") or _num(n1) == 1 else parts + "s")
    return f"{n1} upper {upper} and {n2} lower {parts}{rest}"


_ADJ = r"((?:[a-z-]+ ){0,2}?)"
_ON_TOP = r"(?:on top|at the top|across the top|along the top|up top)"
_BELOW = (r"(?:below|beneath|underneath|under them|below them|beneath them|at the bottom|"
          r"on the bottom|down below)")
_FRONT = r"(drawers?|doors?)"
# "two doors above and two below": "above" with nothing after it is "on top"
_UP = rf"(?:{_ON_TOP}|above(?=,? and\b))"
_TOP_ROW = re.compile(
    rf"\b{_N} {_ADJ}{_FRONT} (side by side |in a row )?{_UP},? (?:and|with|over|above) "
    rf"{_N} {_ADJ}{_FRONT}( side by side| in a row)?(?: {_BELOW})?\b")
# "four doors, two on top and two below": the count shared out between the tiers
_SHARES = re.compile(
    rf"\b{_N} {_ADJ}{_FRONT},? (?:with )?{_N} (?:of them )?{_UP},? and {_N} {_BELOW}"
    rf"( side by side| in a row| in {_N} columns)?")
_SPLIT = re.compile(
    rf"\b{_N} {_FRONT},? (?:with )?the (?:top|upper|first) (?:one|[a-z]+) (?:is |being )?"
    r"(?:split|divided) (?:into|in) (?:two|2)(?: (?:small(?:er)? )?(?:ones|halves|[a-z]+))?\b")


def _top_row(sentence: str) -> tuple[str, list[_Fact]]:
    """A row of several parts at the top over the rest of that part kind, as a count and a
    ``per_row`` fact (parts per row, top row first): "two small drawers on top and three
    large drawers below" is 5 drawers, [2, 1, 1, 1] (the lower ones one to a row unless said
    side by side: [2, 3]); "five drawers, the top one split into two" is 6 drawers, [2, 1, 1,
    1, 1] (the top one becomes two)."""
    facts: list[_Fact] = []

    def rows(word: str, a: int, b: int, row2) -> list[int]:
        # doors below a row of doors stand side by side (a cupboard's "two doors on top and
        # two at the bottom" is two pairs; a full-width door there is twice as wide as any
        # door of the data); drawers below are one to a row unless said side by side, as a
        # chest's long drawers under its small ones
        return [a, b] if row2 or word.startswith("door") else [a] + [1] * b

    def tiers(m: re.Match) -> str:
        n1, w1, n2, w2, row2 = (m.group(k) for k in (1, 3, 5, 7, 8))
        if w1.rstrip("s") != w2.rstrip("s") or _num(n1) < 2 or "stack" in m.group(2):
            return m.group(0)
        a, b = _num(n1), _num(n2)
        facts.append(_Fact("per_row", [rows(w1, a, b, row2)], m.start(), m.start(), "pre"))
        # the counts as said, so that a restated count ("five drawers: two small ones on
        # top and three ...") is read as before; the row is the per_row fact's
        return f"{n1} {m.group(2)}{w1} and {n2} {m.group(6)}{w2}"

    def shares(m: re.Match) -> str:
        n, adj, w = _num(m.group(1)), m.group(2), m.group(3)
        a, b = _num(m.group(4)), _num(m.group(5))
        cols = _num(m.group(7)) if m.group(7) else 0
        if a + b != n or n < 2 or "stack" in adj or (cols and (cols < 2 or b % cols)):
            return m.group(0)
        if cols:            # "one on top and six below in two columns": 1, then rows of 2
            per_row = [a] + [cols] * (b // cols)
        elif a >= 2 or w.startswith("door") or m.group(6):
            per_row = rows(w, a, b, m.group(6))
        else:               # "one on top and two below": a column, as the words say
            return m.group(0)
        facts.append(_Fact("per_row", [per_row], m.start(), m.start(), "pre"))
        return f"{m.group(1)} {adj}{w}"

    def split(m: re.Match) -> str:
        n, w = _num(m.group(1)), m.group(2)
        if n < 2:
            return m.group(0)
        facts.append(_Fact("per_row", [[2] + [1] * (n - 1)], m.start(), m.start(), "pre"))
        return f"{n + 1} {w}"

    sentence = _SHARES.sub(shares, _TOP_ROW.sub(tiers, sentence))
    return _SPLIT.sub(split, sentence), facts


def _is_part(word: str) -> bool:
    toks = _tokenize(word)
    return len(toks) == 1 and toks[0].kind == "PART"


def _rewrite_counts(sentence: str) -> tuple[str, list[_Fact]]:
    """Rewrite grid wordings that carry a count ("two rows of three drawers" -> "6 drawers",
    "a 3 x 3 keypad" -> "9 keypad buttons") and return the arrangement facts they state."""
    facts: list[_Fact] = []
    # a spec list's "drawers: 4, doors: 2" is "4 drawers, 2 doors" (the counts had not been
    # read, and the network made four doors)
    sentence = re.sub(rf"\b([a-z]+)\s*[:=]\s*{_N}(?=\s*(?:$|[,;)]|and\b|plus\b))",
                      lambda m: f"{m.group(2)} {m.group(1)}" if _is_part(m.group(1))
                      else m.group(0), sentence)
    # "three rows with three drawers per row" is "three rows of three drawers"
    sentence = re.sub(rf"\b{_N} (rows|columns|stacks) (?:with|containing|holding|of) {_N} "
                      rf"([a-z]+) (?:per|in each|each|a) (?:row|column|stack)\b",
                      r"\1 \2 of \3 \4", sentence)
    # "two rows of drawers, three in each row" is "two rows of three drawers" (nothing had
    # been counted)
    sentence = re.sub(rf"\b{_N} (rows|columns) of ([a-z]+),? (?:with |each with )?{_N}"
                      rf"(?: [a-z]+)? (?:in each|per|each|to a|in every) (?:row|column)\b",
                      r"\1 \2 of \4 \3", sentence)

    # "a top row of five and a bottom row of five (drawers)" is "two rows of five"
    sentence = re.sub(rf"\b(?:an? |the )?top row of {_N}((?: [a-z]+)?),? (?:and|with|over|above|"
                      rf"plus) (?:an? |the )?bottom (?:row|one) of {_N}\b",
                      lambda m: (f"two rows of {m.group(1)}{m.group(2)}"
                                 if _num(m.group(1)) == _num(m.group(3)) else m.group(0)),
                      sentence)

    # "two upper doors and two lower doors" / "two upper and two lower doors" is "two rows of
    # two doors"; "three upper and two lower doors" is "three upper doors and two lower doors"
    sentence = re.sub(rf"\b{_N} (?:upper|top) ((?:[a-z-]+ ){{0,2}}?)(?:and|plus|over|above) "
                      rf"{_N} (?:lower|bottom) ([a-z-]+)(?: ([a-z]+))?\b", _tiers, sentence)

    # "3 over 3 drawers" is two rows of three (it had been three drawers), "2 over 3 drawers"
    # two drawers on top and three below (a chest's "two over three"), "1 over 2 drawers" one
    # over a row of two
    def over(m: re.Match) -> str:
        a, b, adj, w = m.groups()
        if _num(a) == _num(b):
            return f"two rows of {a} {adj}{w}"
        w = w if w.endswith("s") else w + "s"
        if _num(a) == 1:             # "1 over 2 drawers": a wide one over a row of two
            return f"{_num(a) + _num(b)} {adj}{w}, {a} on top and {b} below side by side"
        return f"{a} {adj}{w} on top and {b} {adj}{w} below"
    sentence = re.sub(rf"\b{_N} over {_N} {_ADJ}{_FRONT}\b", over, sentence)

    # the top tier said last ("three big drawers and two small drawers on top") or as what
    # it is on ("two small drawers on top of three large ones"): said top first, as below
    # (the five had been read as all on top, and the chest made three small ones on top)
    def top_said_last(m: re.Match, top_first: bool) -> str:
        n1, a1, w1, n2, a2, w2 = m.groups()
        if w1.rstrip("s") != w2.rstrip("s"):
            return m.group(0)
        if top_first:
            return f"{n1} {a1}{w1} on top and {n2} {a2}{w2} below"
        return f"{n2} {a2}{w2} on top and {n1} {a1}{w1} below"
    sentence = re.sub(rf"\b{_N} {_ADJ}{_FRONT} and {_N} {_ADJ}{_FRONT} {_ON_TOP}\b",
                      lambda m: top_said_last(m, False), sentence)
    sentence = re.sub(rf"\b{_N} {_ADJ}{_FRONT} on top of {_N} {_ADJ}{_FRONT}\b",
                      lambda m: top_said_last(m, True), sentence)

    # "two small drawers on top and three large drawers below": a row of two over a column of
    # three; "five drawers, the top one split into two": a row of two over four
    sentence, tiered = _top_row(sentence)
    facts += tiered

    # "six pairs of drawers side by side": six rows of two
    sentence = re.sub(rf"\b{_N} pairs of ((?:[a-z]+ )?[a-z]+) side by side\b",
                      r"\1 rows of two \2", sentence)

    out, pos = [], 0
    pat = re.compile(
        rf"\b(?:in |into |as )?(?:a |an )?{_N}\s?(?:x|×|by)\s?{_N}\s(grid|array|keypad|matrix|layout)(\s+of\b)?"
        rf"|\b{_N} (rows|columns|stacks) of {_N}\b(\s+(?=\w))?"
        rf"|\b(?:a |an |the |its |their |two |both )?(?:keypads?|number ?pads?|numpads?)"
        rf"(?!\s+(?:buttons?|keys))( of\b)?")
    for m in pat.finditer(sentence):
        out.append(sentence[pos:m.start()])
        here = sum(len(x) for x in out)
        g = m.groups()
        if g[0] is not None:                 # R x C grid / keypad
            R, C = _num(g[0]), _num(g[1])
            arr = {"layout": "grid" if R > 1 and C > 1 else ("row" if R == 1 else "column"),
                   "rows": R, "columns": C}
            if g[2] == "keypad" and not g[3]:
                text = f"{R * C} keypad buttons"
                mode = "pre"
            elif g[3]:
                text = f"{R * C}"
                mode = "pre"
            else:
                text = "in a grid"
                mode = "post"
            for k, v in arr.items():
                facts.append(_Fact(k, [v], here, here if mode == "pre" else here + len(text), mode))
            out.append(text + (" " if mode == "pre" and not text.endswith("buttons") else ""))
        elif g[4] is not None:               # N rows of M (drawers)
            a, b = _num(g[4]), _num(g[6])
            R, C = (a, b) if g[5] == "rows" else (b, a)      # columns and stacks of M
            followed = g[7] is not None and _part_follows(sentence[m.end():])
            if followed:
                text = f"{R * C} "
                mode = "pre"
            else:                            # (the space the match took stays)
                text = "in a grid" + (" " if g[7] else "")
                mode = "post"
            lay = "grid" if R > 1 and C > 1 else ("row" if R == 1 else "column")
            for k, v in (("layout", lay), ("rows", R), ("columns", C)):
                facts.append(_Fact(k, [v], here, here if mode == "pre" else here + len(text), mode))
            out.append(text)
        else:                                 # "a keypad" (of ...)
            out.append("" if g[8] else "several keypad buttons")
        pos = m.end()
    out.append(sentence[pos:])
    return re.sub(r"[ ]{2,}", " ", "".join(out)) if not facts else "".join(out), facts


def _part_follows(text: str) -> bool:
    """The next few words name a part ("three drawers", "small doors")."""
    for k, t in enumerate(_tokenize(text)[:4]):
        if t.kind == "PART":
            return True
        if t.kind == "PUNCT" or (t.kind == "WORD" and t.text in STOP_WORDS):
            return False
    return False


_SPATIAL_PATTERNS: list[tuple[str, str, str]] = [
    # (key, regex, mode); values come from group 1 (and 2) or the fixed value after '='
    ("hinge", rf"\bhinged (?:on|at|along|to) (?:the |its |their )?{_SIDE}(?:[- ]hand)?(?: sides?| edges?| ends?)?"
              rf"(?:,? (?:and|or) (?:on |at )?(?:the |its )?{_SIDE}(?:[- ]hand)?(?: sides?| edges?)?)?", "post"),
    ("hinge", rf"\b{_SIDE}[- ]hinged\b", "pre"),
    ("hinge", rf"\bwith (?:a|its|the|their) {_SIDE}(?:[- ]hand)? hinges?\b", "post"),
    ("hinge", rf"\bhinges? (?:is |are |sits? |sit |runs? )?(?:on|at|along) (?:the |its )?{_SIDE}(?: side| edge)?\b", "post"),
    ("hinge", rf"\b(?:at|on|by) (?:the|its) {_SIDE} hinges?\b", "post"),
    ("hinge+sideways", r"\b(?:swings?|opens?|swinging|opening) (?:open |out )?(?:to|towards) the (left|right)\b", "post"),
    ("opens=down", r"\b(?:opens?|swings?|folds?|drops?|pulls?|flips?|tips?|falls?|tilts?)(?: open| out)?,? ?down(?:ward|wards)?\b", "post"),
    ("opens=down", r"\b(?:drop|fold|pull|flip)[- ]down\b", "pre"),
    ("opens=down", r"\bdrops open\b", "post"),
    ("opens=up", r"\b(?:opens?|swings?|flips?|lifts?|folds?|tilts?|lifting|flipping)(?: open| out)?,? ?up(?:ward|wards)?\b", "post"),
    ("opens=up", r"\b(?:flip|lift|swing)[- ]up\b", "pre"),
    ("opens=sideways", r"\b(?:opens?|swings?|swinging|opening)(?: open| out)? (?:sideways|to the side|to one side)\b", "post"),
    ("opens=sideways+hinge=side", r"\bside[- ](?:opening|hinged)\b", "pre"),
    ("layout=column", r"\b(?:stacked(?: vertically| up)?(?: one (?:above|on top of|over) (?:the other|another))?"
                      r"|one (?:above|on top of|over|below|under) (?:the other|another)"
                      r"|on top of (?:eachother|oneanother)|in (?:a|one) (?:single |vertical |tall )*(?:column|stack)"
                      r"|vertically stacked|in a vertical line)\b", "post"),
    ("layout=column", r"\b(?:a |one |single )?(?:vertical )?(?:stack|column|tower) of\b", "pre"),
    ("layout=row", r"\b(?:side[- ]by[- ]side|in (?:a|one) (?:single |horizontal |neat |straight )?(?:row|line)"
                   r"|next to (?:eachother|oneanother)|beside (?:eachother|oneanother)"
                   r"|in a horizontal line|one (?:beside|next to|by) (?:the other|another))\b", "post"),
    ("layout=row", r"\b(?:a |one |single )?(?:horizontal |neat |straight )?row of\b", "pre"),
    ("layout=row", r"\b(?:double|french)(?=[- ]doors?\b)", "pre"),   # a pair side by side
    ("layout=grid", r"\bin a grid\b", "post"),
    ("down-across", rf"\b{_N} (?:tall|high|down),? (?:and |by |x |× )?{_N} (?:wide|across)\b", "post"),
    ("across", rf"\b{_N} (?:across|wide)(?:,? (?:and |by |in |x |× )?{_N} (?:down|high|deep|tall))?", "post"),
    ("grid-bare", rf"\b(?:arranged |laid out |set out )?(?:in )?{_N}\s?(?:x|×|by)\s?{_N}\b"
                  rf"(?!\s?(?:cm|mm|m|in|inch|inches|ft|feet|foot|meters?|metres?|centimet\w*|\"|'))", "post"),
    ("over", rf"\b{_N} over {_N}\b", "post"),
    ("relit", r"\b(above|below|under|underneath|beneath|on top of|beside|next to|alongside) "
              r"(?:it|them)\b", "post"),
    ("vpos+hpos", r"\b(?:on|at|in) the (top|bottom)[- ](left|right|cent(?:er|re))\b", "post"),
    ("vpos+row", r"\b(?:across|along) the (top|bottom)\b"
                 r"|\b(?:in|on|along|across) the (top|bottom|upper|lower) row\b", "post"),
    ("layout=row", r"\bacross the (?:front|panel|control panel|face)\b", "post"),
    ("rows+columns", rf"\b{_N} (rows|columns),? (?:and |by |x |× )?{_N} (?:rows|columns)\b", "post"),
    ("rows", rf"\bin {_N} (?:horizontal )?rows\b", "post"),
    ("columns", rf"\bin {_N} (?:vertical )?columns\b", "post"),
    # "over" only before a part ("one drawer over two doors"; "over 2 m tall" is no place)
    ("relation", r"\b(above|on top of|below|under|underneath|beneath|over|beside|next to"
                 r"|alongside)\b(?!-)(?! eachother| oneanother)(?: (?:the|a|an|its|their|both))?",
     "post"),
    ("sideof", r"\b(?:to|on|at) the (left|right)(?:[- ]hand)?(?: side)? of\b(?: (?:the|a|an|its|their|both))?", "post"),
    ("hpos", r"\b(?:the |its )?(left|right)[- ](?:hand )?half (?:is|has|holds|contains|with|:)", "pre"),
    ("hpos", r"\b(?:on|at|to|in) the (left|right)(?:[- ]hand)?(?: side| end| half)?\b", "post"),
    # "a door at each end (of the sideboard)", "drawers on both sides": one on the left, one
    # on the right ("a button on either side of the dial" is about the dial, not the body)
    ("hpos=left+hpos=right", r"\b(?:at|on) (?:each|either|both) ends?\b"
                             r"|\b(?:at|on) (?:each|either|both) sides?\b(?! of)", "post"),
    ("hpos=middle", r"\b(?:(?:sits? |placed |set )?(?:in|at) the (?:middle|cent(?:er|re))"
                    r"(?: of (?:the |its |their )?(?:front|door|panel|control panel|console|body))?"
                    r"|cent(?:er|re)d(?: on (?:the |its )?(?:front|door|panel))?)\b"
                    r"(?! (?:row|drawer|shelf|one|of))", "post"),
    ("vpos", r"\b(?:on|at|near) the (top|bottom)\b(?! of)|\b(?:on|up) (top)\b(?! of)|\bat the (base)\b", "post"),
    # "a keypad at the top of its door": the upper part of the panel it sits on
    ("vpos", r"\b(?:at|near) the (top|bottom) (?:part |half |edge )?of (?:the |its |their )?"
             r"(?:front|door|panel|control panel|console)\b", "post"),
    # "a drawer at the top of the cabinet": the upper part of the object itself
    ("vpos", r"\b(?:at|near|in) the (top|bottom) (?:part |half |end )?of (?:the |its |this |that )?"
             r"(?!(?:front|door|panel|control panel|console|drawer|lid|tray|shelf)s?\b)"
             r"[a-z]+(?: [a-z]+)?\b", "post"),
]
_COMPILED = [(k, re.compile(r), m) for k, r, m in _SPATIAL_PATTERNS]
_ABOVE = {"above", "over", "on top of"}
_BESIDE = {"beside", "next to", "alongside"}
_PRE_SIDE = {"left": ("hpos", "left"), "right": ("hpos", "right"), "left-hand": ("hpos", "left"),
             "right-hand": ("hpos", "right"), "top": ("vpos", "top"), "bottom": ("vpos", "bottom"),
             "upper": ("vpos", "top"), "lower": ("vpos", "bottom")}


def _relation(word: str) -> str:
    return "above" if word in _ABOVE else "beside" if word in _BESIDE else "below"


def _listed_before(toks: list[_Tok], at: int) -> list[_Tok]:
    """The parts of the list that ends right before character ``at`` ("5 knobs and 2
    buttons"): part nouns with their counts, joined by "and" or commas."""
    out: list[_Tok] = []
    for t in reversed([t for t in toks if t.end <= at]):
        if t.kind == "PART":
            out.append(t)
        elif not (t.kind in ("NUM", "DET", "MULT") or t.text in ("and", ",")):
            break
    return out[::-1]


def _spatial_facts(sentence: str, toks: list[_Tok]) -> list[_Fact]:
    """Every spatial phrase of a sentence (spans of earlier patterns are not re-read)."""
    work = sentence
    facts: list[_Fact] = []
    for key, rx, mode in _COMPILED:
        for m in rx.finditer(work):
            a, b = m.span()
            vals = [v for v in m.groups() if v]
            if key in ("relation", "sideof"):
                part = None
                for t in [t for t in toks if t.start >= b][:5]:   # "above a row of three buttons"
                    if t.kind == "PART":
                        part = t
                        break
                    if t.kind not in ("WORD", "NUM", "DET", "MULT", "DIST") or \
                            (t.text in STOP_WORDS and t.text not in ("of", "its", "their")):
                        break           # "above each of its three doors" reads on
                if key == "sideof":
                    # "drawers to the right of the door": right of it, and the door on the
                    # left (a phrase about no part, "left of the panel", is a plain side)
                    facts.append(_Fact("hpos", [vals[0]], a, b if part is None else part.end,
                                       "post", None if part is None else part.value))
                    if part is not None:
                        other = "left" if vals[0] == "right" else "right"
                        facts.append(_Fact("hpos", [other], part.start, part.start, "pre",
                                           implied=True))
                        b = part.end
                elif part is not None:
                    rel = _relation(vals[0])
                    facts.append(_Fact(rel, [part.value], a, part.end, "post", part.value))
                    b = part.end
                elif vals[0] != "over":   # "a door underneath": below the part named before
                    facts.append(_Fact("relprev", [_relation(vals[0])],
                                       a, b, "post"))
            elif key == "across":
                facts.append(_Fact("columns", [_num(vals[0])], a, b, mode))
                if len(vals) > 1:
                    facts.append(_Fact("rows", [_num(vals[1])], a, b, mode))
            elif key in ("down-across", "grid-bare"):   # "3 tall, 4 wide", "arranged 3 by 3"
                for k2, v2 in (("rows", _num(vals[0])), ("columns", _num(vals[1]))):
                    facts.append(_Fact(k2, [v2], a, b, mode))
            elif key == "over":
                if _num(vals[0]) == _num(vals[1]):
                    for k2, v2 in (("layout", "grid" if _num(vals[0]) > 1 else "column"),
                                   ("rows", 2), ("columns", _num(vals[0]))):
                        facts.append(_Fact(k2, [v2], a, b, mode))
            elif key == "relit":
                # "three drawers side by side above them": about the part named just before;
                # "and, below them, two doors": about the part named next
                before = [t for t in toks if t.end <= a and t.kind in ("PART", "PUNCT")]
                mode2 = "post" if before and before[-1].kind == "PART" else "next"
                facts.append(_Fact("relit", [_relation(vals[0])], a, b, mode2))
            elif key == "rows+columns":
                first, other = _num(vals[0]), _num(vals[2])
                R, C = (first, other) if vals[1] == "rows" else (other, first)
                for k2, v2 in (("rows", R), ("columns", C)):
                    facts.append(_Fact(k2, [v2], a, b, mode))
            elif key == "vpos+row":      # "along the top", "in the lower row"
                side = {"upper": "top", "lower": "bottom"}.get(vals[0], vals[0])
                listed = _listed_before(toks, a)   # "5 knobs and 2 buttons along the top"
                if len(listed) < 2 or any(t.value not in CONTROLS for t in listed):
                    listed = []        # "two doors and one drawer along the bottom": the drawer
                nearest = [t for t in toks if t.end <= a and t.kind == "PART"][-1:]
                for t in listed or [None]:
                    at, to = (a, b) if t is None else (t.end, t.end)
                    facts.append(_Fact("vpos", [side], at, to, mode))
                    of = t if t is not None else (nearest[0] if nearest else None)
                    if of is None or of.plural:    # "one drawer along the bottom": no row
                        facts.append(_Fact("layout", ["row"], at, to, mode))
            elif key == "vpos+hpos":
                facts.append(_Fact("vpos", [vals[0]], a, b, mode))
                side = "middle" if vals[1].startswith("cent") else vals[1]
                facts.append(_Fact("hpos", [side], a, b, mode))
            elif key == "hinge+sideways":
                facts.append(_Fact("hinge", vals, a, b, mode))
                facts.append(_Fact("opens", ["sideways"], a, b, mode))
            elif "=" in key:
                for kv in key.split("+"):
                    k, v = kv.split("=")
                    facts.append(_Fact(k, [v], a, b, mode))
            elif key in ("rows", "columns"):
                facts.append(_Fact(key, [_num(vals[0])], a, b, mode))
            elif key == "vpos":
                facts.append(_Fact("vpos", ["bottom" if vals[0] == "base" else vals[0]], a, b, mode))
            else:
                facts.append(_Fact(key, [_SIDE_NAME.get(v, v) for v in vals], a, b, mode))
            work = work[:a] + " " * (b - a) + work[b:]
    # side adjectives right before a part: "a left door", "the upper drawer"
    for k, t in enumerate(toks):
        if t.kind == "WORD" and t.text in _PRE_SIDE and work[t.start:t.end] == t.text:
            nxt = toks[k + 1:k + 3]
            if nxt and (nxt[0].kind == "PART" or (len(nxt) > 1 and nxt[0].kind in ("WORD", "MOTION")
                                                   and nxt[1].kind == "PART")):
                key, val = _PRE_SIDE[t.text]
                facts.append(_Fact(key, [val], t.start, t.end, "pre"))
    for f in facts:
        if f.key in ("hpos", "vpos") and f.mode == "post" and _PANEL.search(sentence[:f.start]):
            f.panel = True
    return facts


# "a control panel at the top with two dials": the place is the panel's, so its controls'
_PANEL = re.compile(r"\b(?:control )?(?:panel|console|fascia|backsplash)\s*$")
CONTROLS = ("knob", "dial", "button")


# an open place of the body, no part of it: "a drawer and an open shelf below" puts the
# shelf below the drawer, so the drawer at the top
PLACES = {"shelf", "shelves", "space", "compartment", "compartments", "cubby", "cubbies",
          "niche", "nook", "opening", "cavity"}


def _place_said(toks: list[_Tok], start: int, end: int) -> bool:
    """Whether an open place (``PLACES``) is named between characters ``start`` and ``end``,
    with no part named after it there: what a relation word at ``end`` is said of."""
    between = [t for t in toks if start <= t.start and t.end <= end]
    places = [n for n, t in enumerate(between) if t.text in PLACES]
    return bool(places) and not any(t.kind == "PART" for t in between[places[-1]:])


def _about_place(f: _Fact, toks: list[_Tok], parts: list[_Tok]) -> _Fact | None:
    """A relation said of an open place, as the part's own position: "an open shelf below"
    (the part named before it at the top), "an open shelf above a drawer" (the drawer at the
    bottom); None when the relation is not said of a place."""
    said_before = f.key == "relprev" or (f.key == "relit" and f.mode == "post")
    if said_before or (f.key in ("above", "below") and f.relation_to is not None):
        before = [t for t in parts if t.end <= f.start]
        if _place_said(toks, before[-1].end if before else 0, f.start):
            rel = f.values[0] if said_before else f.key
            return _Fact("vpos", ["bottom" if rel == "above" else "top"], f.start, f.end,
                         "post" if said_before else "next", f.relation_to)
    return None


def _of(toks: list[_Tok], t: _Tok) -> bool:
    """Whether part token ``t`` is named as a place: "of" within the two words before it
    ("in the middle of the door", "on top of a cabinet")."""
    i = toks.index(t)
    return any(x.text == "of" for x in toks[max(0, i - 2):i])


def _attach(facts: list[_Fact], toks: list[_Tok], earlier: list[str],
            spatial: dict[str, dict]) -> list[str]:
    """Attach each fact to the part it describes and merge it into ``spatial``; returns the
    labels a hinge or opening fact was said of (they turn on a hinge: revolute)."""
    hinged: list[str] = []
    parts = [t for t in toks if t.kind == "PART"]
    for f in sorted(facts, key=lambda f: f.implied):     # what is said before what is implied
        allowed = HINGED if f.key in ("hinge", "opens") else \
            ARRANGED if f.key in ARRANGEMENT_KEYS else vocab.COUNTABLE_LABELS
        place = _about_place(f, toks, parts)
        if place is not None:
            target = place.relation_to or ([t.value for t in parts if t.end <= f.start]
                                           or [None])[-1]
            if target in vocab.COUNTABLE_LABELS:
                _merge(spatial.setdefault(target, {}), "vpos", place.values)
            continue
        if f.key == "relit":
            # "below it, a small door" / "three doors below them": one part kind relative to
            # the one named before
            before = [t.value for t in parts if t.end <= f.start]
            after = [t.value for t in parts if t.start >= f.end]
            if f.mode == "post" and before:
                subj = before[-1]
                # "it" is not a part named as a place ("a dial in the middle of the door
                # with a handle below it": below the dial)
                named = [t.value for t in parts if t.end <= f.start and not _of(toks, t)]
                objs = [v for v in named if v != subj] or \
                    [v for v in before[:-1] if v != subj] or [v for v in earlier if v != subj]
            else:
                subj = after[0] if after else None
                objs = [v for v in before if v != subj] or [v for v in earlier if v != subj]
            if subj is not None and objs:
                _merge(spatial.setdefault(subj, {}), f.values[0], [objs[-1]])
            continue
        if f.panel:
            # the controls named after the panel in this sentence, else those before it
            after = [t.value for t in parts if t.start >= f.end and t.value in CONTROLS]
            before = [t.value for t in parts if t.end <= f.start and t.value in CONTROLS]
            for lab in dict.fromkeys(after or before):
                _merge(spatial.setdefault(lab, {}), f.key, f.values)
            continue
        target = None
        # a phrase right before a part noun (adjectives between) is about that part:
        # "stacked hinged doors", "a drop-down door"
        nxt = [t for t in toks if t.start >= f.end][:3]
        for t in nxt:
            if t.kind == "PART":
                target = t.value if t.value in allowed else None
                break
            if t.kind not in ("WORD", "MOTION") or t.text in STOP_WORDS:
                break
            if f.mode != "pre" and t.kind == "WORD" and t.text not in SIDE_ADJECTIVES:
                break   # "... side by side that ..." is not a pre-modifier
        if f.mode == "pre" and target is None:      # "a stack of 3 drawers", up to a comma
            for t in [t for t in toks if t.start >= f.end][:6]:
                if t.kind == "PUNCT":
                    break
                if t.kind == "PART" and t.value in allowed:
                    target = t.value
                    break
        if target is None:
            before = [t for t in parts if t.end <= f.start and t.value in allowed]
            if f.key in ARRANGEMENT_KEYS:
                # an arrangement is of several parts: "two knobs below the door, side by side"
                before = [t for t in before if t.plural] or before
            target = before[-1].value if before else None
        if target is None:
            prev = [lab for lab in earlier if lab in allowed]
            target = prev[-1] if prev else None
        if target is None:
            after = [t.value for t in parts if t.start >= f.end and t.value in allowed]
            target = after[0] if after else None
        if target is None or target == f.relation_to:
            continue
        if f.key == "relprev":
            subject = [t for t in parts if t.end <= f.start and t.value == target]
            other = [t.value for t in parts if subject and t.end <= subject[-1].start
                     and t.value != target]
            if other:
                f = _Fact(f.values[0], [other[-1]], f.start, f.end, f.mode)
            elif f.values[0] == "beside":   # beside nothing named: no place
                continue
            else:
                f = _Fact("vpos", ["top" if f.values[0] == "above" else "bottom"], f.start,
                          f.end, f.mode)
        facts_of = spatial.setdefault(target, {})
        if f.implied and f.key in facts_of:
            continue
        if f.key in ("hinge", "opens"):
            hinged.append(target)
        if f.key in ARRANGEMENT_KEYS:
            facts_of[f.key] = f.values[0]
        else:
            _merge(facts_of, f.key, f.values)
    return hinged


def _merge(facts_of: dict, key: str, values) -> None:
    """Add ``values`` to a part's set-valued fact ``key`` (sides, relations)."""
    facts_of[key] = sorted(set(facts_of.get(key, [])) | set(values))
