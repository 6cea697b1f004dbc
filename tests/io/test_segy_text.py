"""The SEG-Y textual header: lines wrapped by words onto its 80-column cards, read back with segyio."""

import logging

import numpy as np
import pytest
import segyio
import xarray as xr
from scenes import FS, PULSE, point_ping

from clbeam.io.pingwrite import write_ping_file
from clbeam.io.segy import CARD_TEXT_COLUMNS, TEXT_CARDS, text_header
from clbeam.seabed.profile import write_profile

CARD = 80  # columns of a SEG-Y rev 1 textual-header card


def written_cards(path, lines):
    """The 40 cards segyio reads back from a one-trace SEG-Y file whose header was made of ``lines``."""
    spec = segyio.spec()
    spec.format, spec.samples, spec.tracecount = 5, np.arange(8), 1
    with segyio.create(str(path), spec) as f:
        f.text[0] = text_header(lines)
        f.trace[0] = np.zeros(8, dtype=np.float32)
    with segyio.open(path, ignore_geometry=True) as f:
        text = bytes(f.text[0]).decode("ascii")
    assert len(text) == 40 * CARD
    return [text[CARD * k:CARD * (k + 1)] for k in range(40)]


def card_texts(cards):
    """The text of cards 1-38 after the ``C nn `` prefix each must carry."""
    for k, card in enumerate(cards, start=1):
        assert card[:4] == f"C{k:>2} "
    return [card[4:].rstrip() for card in cards[:TEXT_CARDS]]


def groups(texts):
    """The cards of each line: a card that does not start with two spaces, then its continuations."""
    out = []
    for t in texts:
        if t.startswith("  ") and out:
            out[-1].append(t[2:])
        elif t:
            out.append([t])
    return out


def test_long_lines_wrap_at_spaces_and_every_word_reads_back_whole(tmp_path):
    rng = np.random.default_rng(7)
    letters = np.array(list("ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-();:/|"))
    lines = [" ".join("".join(rng.choice(letters, rng.integers(1, 19))) for _ in range(rng.integers(1, 16)))
             for _ in range(10)]
    lines[3] = "BEAM: 0 DEG FROM NADIR, EARTH-REFERENCED (ROLL, HEAVE COMPENSATED; PITCH IGNORED)"  # 82 characters
    texts = card_texts(written_cards(tmp_path / "t.sgy", lines))
    assert all(len(t) <= CARD_TEXT_COLUMNS for t in texts)
    cards_of = groups(texts)
    assert len(cards_of) == len(lines)
    for line, cards in zip(lines, cards_of):
        # the words come back in order, none cut in two: the same tokens as the line
        assert " ".join(cards).split() == line.split()
        for card, nxt in zip(cards, cards[1:]):
            assert len(card) + 1 + len(nxt.split()[0]) > CARD_TEXT_COLUMNS - (0 if card is cards[0] else 2)
    assert cards_of[3] == ["BEAM: 0 DEG FROM NADIR, EARTH-REFERENCED (ROLL, HEAVE COMPENSATED; PITCH", "IGNORED)"]


def test_a_word_longer_than_a_card_is_split_and_nothing_is_lost(tmp_path):
    word = "".join(chr(ord("A") + k % 26) for k in range(CARD_TEXT_COLUMNS + 30))
    texts = card_texts(written_cards(tmp_path / "w.sgy", [f"SOURCE FILE: {word}.nc"]))
    assert "".join(t.strip() for t in texts if t) == f"SOURCE FILE: {word}.nc"


def test_cards_39_and_40_are_rev1s_and_text_past_card_38_is_dropped_with_a_warning(tmp_path, caplog):
    lines = [f"LINE {k}" for k in range(1, 46)]
    with caplog.at_level(logging.WARNING, logger="clbeam.io.segy"):
        cards = written_cards(tmp_path / "n.sgy", lines)
    assert card_texts(cards) == lines[:TEXT_CARDS]
    assert cards[38][4:].rstrip() == "SEG Y REV1" and cards[39][4:].rstrip() == "END TEXTUAL HEADER"
    assert "7 dropped" in caplog.text


@pytest.mark.parametrize("name_length", [20, 120])
def test_a_profiles_header_keeps_every_word_of_its_lines(tmp_path, name_length):
    ping = point_ping([0.0, 0.0, 40.0], record_s=0.07)
    ds = xr.Dataset({
        "samples": (("ping", "channel", "sample"), ping.samples[None], {"kind": "raw"}),
        "sample_rate": ((), FS), "t0": (("ping",), [0.0]),
        "element_y": (("channel",), ping.element_pos_m[:, 1]), "element_z": (("channel",), ping.element_pos_m[:, 2]),
        "source_y": ((), 0.0), "source_z": ((), 0.0), "sound_speed": ((), 1500.0),
        "pulse_f0": ((), PULSE.f0_hz), "pulse_f1": ((), PULSE.f1_hz), "pulse_duration": ((), PULSE.duration_s),
    })
    name = ("p" * name_length)[: name_length - 3] + ".nc"
    write_ping_file(ds, tmp_path / name)
    out = write_profile(tmp_path / name, tmp_path / "p.sgy", plot=False, interp="linear", backend="reference")
    with segyio.open(out.segy_path, ignore_geometry=True) as f:
        text = bytes(f.text[0]).decode("ascii")
    cards_of = groups(card_texts([text[CARD * k:CARD * (k + 1)] for k in range(40)]))
    words = [w for cards in cards_of for w in " ".join(cards).split()]
    # the line the old header cut at 80 columns ("... PITCH IGN") is whole, over two cards
    assert "PITCH" in words and "IGNORED)" in words and "IGN" not in words
    source = next(cards for cards in cards_of if cards[0].startswith("SOURCE FILE:"))
    assert "".join(source).removeprefix("SOURCE FILE:").strip() == name  # a name longer than a card is split
