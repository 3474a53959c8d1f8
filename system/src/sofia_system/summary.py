"""The demo's running summary: one line per step, a table at the end."""

from __future__ import annotations

from dataclasses import dataclass, field


def say(text: str) -> None:
    print(text, flush=True)


@dataclass
class Summary:
    rows: list[tuple[str, str, bool]] = field(default_factory=list)

    def add(self, step: str, result: str, ok: bool) -> None:
        self.rows.append((step, result, ok))
        say(f"{'ok ' if ok else 'FAIL'} {step}: {result}")

    def as_list(self) -> list[dict[str, object]]:
        """The steps for machines: ``[{"step", "result", "ok"}, ...]``."""
        return [{"step": s, "result": r, "ok": ok} for s, r, ok in self.rows]

    @property
    def ok(self) -> bool:
        return all(ok for _, _, ok in self.rows)

    def table(self) -> str:
        width = max(len(s) for s, _, _ in self.rows)
        lines = ["", "SofIA demo summary", "-" * 60]
        lines += [f"{'ok ' if ok else 'FAIL'} {s:<{width}}  {r}" for s, r, ok in self.rows]
        lines.append("-" * 60)
        lines.append("all steps passed" if self.ok else "some steps FAILED (see above and the service logs)")
        return "\n".join(lines)
