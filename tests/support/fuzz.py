"""Hypothesis settings for the fuzz tests: a fixed, derandomized set of examples in `make test` (unit
tests must be deterministic), a long randomized campaign with `make soak` (STAGE_EMU_SOAK_EXAMPLES).

Also the strategies for MS2000 command lines with hostile items (`ms2000_lines`): a word followed by
items made of the command's documented letters and others, `=`, `?`, `+`, `-`, values in and far out
of range, values that are not numbers, missing values, extra and repeated items.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

SOAK_VARIABLE = "STAGE_EMU_SOAK_EXAMPLES"


def fuzz_settings(examples: int) -> settings:
    soak = os.environ.get(SOAK_VARIABLE)
    common: dict[str, Any] = {"deadline": None, "database": None, "suppress_health_check": list(HealthCheck)}
    if soak:
        return settings(max_examples=int(soak), **common)
    return settings(max_examples=examples, derandomize=True, **common)


#: values most module letters accept (counts, codes, volts, fractions) and their near misses
IN_RANGE = st.one_of(
    st.sampled_from(["0", "1", "2", "3", "-1"]),
    st.integers(-2, 260).map(str),
    st.sampled_from(["0.5", "1.5", "-0.25", "0.000001", "7.5", "73", "80", "82", "1000", "1082", "32767"]),
)
#: far out of every range, and beyond the 32-bit firmware variable (MS-26); 1e400 is no number
FAR = st.sampled_from(["1e9", "-1e9", "65536", "2147483648", "99999999999", "-99999999999", "1e400"])
#: what the firmware reads as its numeric prefix or as 0 (MS-25)
NON_NUMERIC = st.sampled_from(["abc", "50?", "1.5abc", "-", ".", "1e", "0x10", "nan", "--1", "+.5"])
VALUES = st.one_of(IN_RANGE, FAR, NON_NUMERIC, st.floats(-1e4, 1e4).map("{:.4f}".format))
#: letters no module documents everywhere, lower case included (MS-10)
OTHER_LETTERS = "XYZFTRMABQxyz"
#: items the grammar cannot key to a letter (MS-31) or reads oddly (spaces around `=`, MS-23)
ODD_ITEMS = st.sampled_from(["=5", "X==1", "X=1=2", "?", "5X", "X = 5", "X=", "Y= -3"])


def ms2000_items(letters: str) -> st.SearchStrategy[str]:
    """One item: a documented letter (from `letters`) or another, with any suffix and value."""
    letter = st.one_of(st.sampled_from(letters or OTHER_LETTERS), st.sampled_from(OTHER_LETTERS))
    return st.one_of(
        st.builds("{}={}".format, letter, VALUES),
        st.builds("{}={}".format, letter, VALUES),
        st.builds("{}{}".format, letter, st.sampled_from("?+-")),
        letter,
        VALUES,
        ODD_ITEMS,
    )


def ms2000_lines(words: Mapping[str, str]) -> st.SearchStrategy[str]:
    """`WORD item…` for a word of `words` (word -> the letters its command documents), in upper or
    lower case, with no items (missing), some, or more than the command takes (extra, repeated)."""

    def line(word: str) -> st.SearchStrategy[str]:
        spelled = st.sampled_from([word, word.lower()])
        items = st.lists(ms2000_items(words[word]), max_size=6)
        return st.builds(lambda w, i: " ".join([w, *i]), spelled, items)

    return st.sampled_from(sorted(words)).flatmap(line)
