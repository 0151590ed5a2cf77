"""What the measurement pages share: sources placed by their `table`, notes by their `section`."""

from __future__ import annotations

from pathlib import Path

from lab.results.pages.page import Page


class MeasurementPage(Page):
    """A page of measurements: tables built from its `source`s, each with a `table` naming where it goes, then the
    notes."""

    def sources(self, table: str) -> list[dict]:
        return [self.data[s["id"]] | {"file": s["summary"], "label": s["label"]} for s in self.spec.get("source", [])
                if s.get("table") == table]

    def files(self) -> dict[Path, bytes]:
        return {self.root / f"{self.name}.md": self.markdown().encode()}
