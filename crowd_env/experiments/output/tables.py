"""One table renderer for the commands' results: plain text padded to the columns, or Markdown."""
from __future__ import annotations

__all__ = ["format_table"]


def format_table(head, rows, *, markdown: bool = False, separator: str = "-+-", align=None) -> str:
    """``rows`` (lists of cells, turned into text) under ``head``. Markdown: a pipe table (a ``|`` inside a cell
    becomes ``/``). Plain text: columns padded to their widest cell, a rule of dashes joined by ``separator``
    under the head, and ``align`` one of ``"<"`` (left, the default) or ``">"`` per column."""
    head = [str(h) for h in head]
    rows = [[str(x) for x in r] for r in rows]
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        return "\n".join(lines + ["| " + " | ".join(x.replace("|", "/") for x in r) + " |" for r in rows])
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(head)]
    align = list(align) if align is not None else ["<"] * len(head)
    fmt = " | ".join(f"{{:{a}{w}}}" for a, w in zip(align, widths))
    return "\n".join([fmt.format(*head), separator.join("-" * w for w in widths)] + [fmt.format(*r) for r in rows])
