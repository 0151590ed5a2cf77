"""What every page declaration shares: its kept sources, `{id.key}` placeholders, the verdict, short notes and the
one folded section of longer ones.

A declaration holds `title`, `verdict` (at most two sentences), arrays of tables `source` (id, label, summary: a kept
JSON; optional `config`, a kept `tax3d train` config.json read as `{id.config...}`), `note` (title, text of at most
NOTE_WORDS words, optional `section`) and `detail` (title, text: the longer explanations, all in one folded section).
`{id.split.metric}` reads a split of a kept evaluation (`success` for success_rate), `{id.key.key}` any key of a kept
JSON, `{paper.ROW.metric.split}` the paper's table of the page's `task`; `{...:.3f}` formats.

What every page says is written once, in shared.toml beside this module: a note may be `shared = "NAME"` with the
ids its slots name (the note's title and text come from `[note.NAME]`), and a source that is a row of `tax3d table
--keep` needs no label.
"""

from __future__ import annotations

import re
import tomllib
from functools import cache
from pathlib import Path

from tax3d.errors import UsageError
from tax3d.metrics import split_rate
from tax3d.variants import FIXED_GOALS, ROWS, paper_key, row_name
from lab.results import kept
from lab.results.commands import shown

SPLITS = ("train", "unseen", "ood")
ALIASES = {"success": "success_rate"}
PLACEHOLDER = re.compile(r"\{([A-Za-z][\w-]*(?:\.[\w-]+)+)(?::([^{}]+))?\}")
NOTE_WORDS = 50
VERDICT_SENTENCES = 2
SENTENCE_END = re.compile(r"[.!?](?=\s+[A-Z`*(\[]|\s*$)")
TABLE_ROW = re.compile(r"table/[\w-]+/(\d+)/(\w+)\.json")


@cache
def shared() -> dict:
    """The text every page, or every page of a kind, shares (shared.toml beside this module)."""
    return tomllib.loads(Path(__file__).with_name("shared.toml").read_text())


def slots(text: str, values: dict[str, str]) -> str:
    """`text` with each `{name}` slot filled from `values`, and each placeholder `{name.key}` read from the id
    `values[name]`; other braces stay."""
    def sub(m: re.Match) -> str:
        name, end = m.groups()
        if name not in values:
            return m.group(0)
        return values[name] if end == "}" else "{" + values[name] + "."
    return re.sub(r"\{(\w+)([}.])", sub, text)


def fold(summary: str, lines: list[str]) -> list[str]:
    return [f"<details><summary>{summary}</summary>", "", *lines, "", "</details>", ""]


def provenance(d: dict) -> str:
    return f"{shown(d['command'])} on {d['machine']}, {d['date']}"


def cell(value, fmt: str) -> str:
    return "-" if value is None else fmt.format(value)


def _fmt(value) -> str:
    if isinstance(value, list):
        return "(" + ", ".join(f"{v:g}" for v in value) + ")"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int):
        return f"{value:,}"
    return f"{value:.2f}"


class Page:
    """One page's declaration with its kept sources loaded; a subclass renders it (`files`)."""

    row_kinds: tuple[str, ...] = ("eval", "fixed-goal")
    required: tuple[str, ...] = ("title", "verdict")

    def __init__(self, file: Path, root: Path, paper: dict, spec: dict):
        missing = [key for key in self.required if key not in spec]
        if missing:
            raise UsageError(f"{file.name}: no {', '.join(missing)}; expected a declaration with "
                             f"{', '.join(self.required)} ({type(self).__module__})")
        self.file, self.root, self.name, self.spec = file, root, file.stem, spec
        self.paper_all, self.paper = paper, paper.get(spec.get("task", ""), {"rows": {}})
        self.rows, self.curves = spec.get("row", []), spec.get("curve", [])
        spec["note"] = [self._shared_note(note) for note in spec.get("note", [])]
        for source in spec.get("source", []):
            if "label" not in source:
                source["label"] = self._source_label(source)
        self.data = {}
        curve_kinds = ("val-curve", "train-log")
        for what, items, kinds in (("row", self.rows, self.row_kinds), ("curve", self.curves, curve_kinds),
                                   ("source", spec.get("source", []), ())):
            for item in items:
                self.data[item["id"]] = self._load(what, item, kinds)
        for note in spec.get("note", []):
            words = len(note["text"].split())
            if words > NOTE_WORDS:
                raise UsageError(f"{file.name}: note {note['title']!r}: {words} words; expected at most {NOTE_WORDS} "
                                 "(a longer text is a [[detail]], in the page's folded section)")

    def _shared_note(self, note: dict) -> dict:
        """A note as declared, or a shared one (`shared = "NAME"`) with its slots read from the note's ids; the
        sources those ids name get the shared label of their slot where they declare none."""
        if "shared" not in note:
            return note
        template = shared()["note"].get(note["shared"])
        if template is None:
            raise UsageError(f"{self.file.name}: note shared = {note['shared']!r}: expected one of "
                             f"{', '.join(shared()['note'])}")
        ids = {k: v for k, v in note.items() if k not in ("shared", "section")}
        for source in self.spec.get("source", []):
            slot = next((k for k, v in ids.items() if v == source["id"] and k in template), None)
            if slot and "label" not in source:
                source["label"] = template[slot]
        return {"title": template["title"], "text": slots(template["text"], ids),
                "section": note.get("section", template.get("section"))}

    def _source_label(self, source: dict) -> str:
        m = TABLE_ROW.fullmatch(source.get("summary", ""))
        if not m:
            raise UsageError(f"{self.file.name}: source {source.get('id')!r}: no label; expected one (only a row of "
                             "`tax3d table --keep`, table/TASK/DEMOS/VARIANT.json, goes without)")
        key = paper_key(m.group(2)) if m.group(2) in ROWS else m.group(2)
        name = key if key in FIXED_GOALS else row_name(key)
        return slots(shared()["source"]["table-row"], {"name": name, "demos": m.group(1)})

    def _load(self, what: str, item: dict, kinds: tuple[str, ...]) -> dict:
        path = self.root / item["summary"]
        if not path.is_file():
            raise UsageError(f"{self.file.name}: {what} {item['id']!r} ({item.get('label', '')}): "
                             f"{path} not found; expected a kept summary")
        data = kept.load(path, kinds)
        if "config" in item:
            data = {**data, "config": kept.config(self.root / item["config"])}
        return {**data, **data.get("splits", {})}

    # -- values ---------------------------------------------------------------------------------------------------
    def value(self, path: str):
        keys = path.split(".")
        if keys[0] != "paper":
            keys = [ALIASES.get(k, k) for k in keys]
        elif keys[1] in self.paper["rows"]:  # paper.ROW.metric.split
            return self.paper["rows"][keys[1]][keys[2]][SPLITS.index(keys[3])]
        node = self.paper_all if keys[0] == "paper" else self.data[keys[0]]
        for k in keys[1:]:
            node = node[int(k)] if isinstance(node, list) else node[k]
        return node

    def fill(self, text: str) -> str:
        def sub(m: re.Match) -> str:
            try:
                value = self.value(m.group(1))
            except (KeyError, IndexError, ValueError):
                raise UsageError(f"{self.file.name}: placeholder {m.group(0)}: no such value in the kept "
                                 "summaries") from None
            if m.group(2):
                return format(value, m.group(2))
            return self._rate(m.group(1)) or _fmt(value)
        return PLACEHOLDER.sub(sub, text.strip())

    def _rate(self, path: str) -> str | None:
        """A success rate as exact as its split's episodes allow (tax3d.metrics.rate), None for any other value."""
        parent, _, last = path.rpartition(".")
        if ALIASES.get(last, last) != "success_rate" or parent.split(".")[0] == "paper":
            return None
        split = self.value(parent)
        return split_rate(split) if isinstance(split, dict) and split.get("episodes") else None

    # -- prose ----------------------------------------------------------------------------------------------------
    def verdict(self) -> str:
        text = self.fill(self.spec["verdict"])
        sentences = len(SENTENCE_END.findall(text))
        if sentences > VERDICT_SENTENCES:
            raise UsageError(f"{self.file.name}: verdict: {sentences} sentences; expected at most "
                             f"{VERDICT_SENTENCES} (the rest is a note)")
        return text

    def notes(self, section: str | None = None) -> list[str]:
        """The short notes of a section (those without one where None), each a paragraph."""
        return [line for note in self.spec.get("note", []) if note.get("section") == section
                for line in (f"**{note['title']}.** {self.fill(note['text'])}", "")]

    def details(self, summary: str = "Notes: how the figures were made and what they show") -> list[str]:
        """The page's one folded section: every longer explanation, in the order declared."""
        details = self.spec.get("detail", [])
        if not details:
            return []
        return fold(summary, [line for d in details for line in (f"**{d['title']}.** {self.fill(d['text'])}", "")])

    def files(self) -> dict[Path, bytes]:
        raise NotImplementedError
