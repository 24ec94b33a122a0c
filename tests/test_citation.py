"""CITATION.cff is a CITATION.cff of version 1.2.0: the keys that version requires, and every
reference with its type, title and authors."""

from __future__ import annotations

from pathlib import Path

import yaml

CITATION = Path(__file__).resolve().parents[1] / "CITATION.cff"


def test_the_citation_file_has_what_cff_1_2_0_requires():
    citation = yaml.safe_load(CITATION.read_text(encoding="utf-8"))
    assert citation["cff-version"] == "1.2.0"
    assert all(citation.get(key) for key in ("message", "title", "authors"))
    references = citation["references"] + ([citation["preferred-citation"]] if "preferred-citation" in citation else [])
    incomplete = [entry.get("title") for entry in references
                  if not all(entry.get(key) for key in ("type", "title", "authors"))]
    assert incomplete == []
    authors = [author for entry in [citation, *references] for author in entry["authors"]]
    assert all("name" in author or "family-names" in author for author in authors)


def test_the_papers_are_cited_by_their_identifiers():
    references = {entry["title"]: entry for entry in yaml.safe_load(CITATION.read_text(encoding="utf-8"))["references"]}
    moglow = references["MoGlow: Probabilistic and controllable motion synthesis using normalising flows"]
    assert (moglow["doi"], moglow["volume"], moglow["issue"], moglow["year"]) == ("10.1145/3414685.3417836", 39, 6, 2020)
    data = references["Motion Capture Dataset for Practical Use of AI-based Motion Editing and Stylization"]
    assert [author["family-names"] for author in data["authors"]] == ["Kobayashi", "Liao", "Inoue", "Yojima", "Takahashi"]
    assert {"type": "other", "value": "arXiv:2306.08861"} in data["identifiers"]
