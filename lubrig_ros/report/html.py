"""Self-contained HTML pages beside the Markdown reports: figures embedded as base64 PNG.

`lubrig report` writes report.html next to report.md and `lubrig paper` comparison.html next to
comparison.md. The page is rendered from the same Markdown (one source of the wording) by a small
converter of the subset these pages use — headings, paragraphs, bullet lists, pipe tables,
images on their own line, inline code, bold, italics and links — so no Markdown package is
needed. Every image is read from disk (relative to the Markdown page) and embedded as a
data: URI, so the page has no external reference and can be mailed or archived on its own.
"""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

from lubrig_ros.core.errors import LubrigError

STYLE = """
body { font-family: system-ui, -apple-system, 'Segoe UI', sans-serif; max-width: 1100px;
       margin: 2em auto; padding: 0 1em; color: #1a1a1a; line-height: 1.45; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #c8c8c8; padding: 0.25em 0.5em; vertical-align: top; }
th { background: #f0f0f0; }
img { max-width: 100%; display: block; margin: 0.6em 0; }
figure { margin: 0.8em 0; } figcaption { font-size: 0.85em; color: #555; }
code { background: #f4f4f4; padding: 0 0.2em; }
"""

_IMAGE_LINE = re.compile(r"^!\[(?P<alt>[^\]]*)\]\((?P<src>[^)\s]+)\)$")
_IMAGE = re.compile(r"!\[([^\]]*)\]\(([^)\s]+)\)")
_LINK = re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)")
_CODE = re.compile(r"`([^`]+)`")
_BOLD = re.compile(r"\*\*([^*]+)\*\*")
_ITALIC = re.compile(r"(?<![*\w])\*([^*\s][^*]*)\*(?![*\w])")


class PageError(LubrigError, ValueError):
    """An image of the page cannot be embedded (missing file); one user-facing line."""


def data_uri(path: Path) -> str:
    """data:image/png;base64,… of a PNG file (SVG as image/svg+xml)."""
    kind = "image/svg+xml" if path.suffix.lower() == ".svg" else "image/png"
    return f"data:{kind};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _image(alt: str, src: str, root: Path) -> str:
    path = (root / src).resolve()
    if not path.is_file():
        raise PageError(f"figure {src!r} of the page is missing ({path})")
    return (
        f'<figure><img alt="{html.escape(alt)}" src="{data_uri(path)}">'
        f"<figcaption>{html.escape(alt)}</figcaption></figure>"
    )


def _inline(text: str, root: Path) -> str:
    """Escape, then apply code, images, links, bold and italics (code spans are left alone)."""
    parts = _CODE.split(text)
    out = []
    images: list[str] = []

    def keep(match: re.Match[str]) -> str:
        images.append(_image(match.group(1), match.group(2), root))
        return f"\x00{len(images) - 1}\x00"

    for i, part in enumerate(parts):
        if i % 2:
            out.append(f"<code>{html.escape(part)}</code>")
            continue
        part = html.escape(_IMAGE.sub(keep, part), quote=False)
        part = _LINK.sub(lambda m: f'<a href="{html.escape(m.group(2))}">{m.group(1)}</a>', part)
        part = _BOLD.sub(r"<strong>\1</strong>", part)
        part = _ITALIC.sub(r"<em>\1</em>", part)
        part = re.sub("\x00(\\d+)\x00", lambda m: images[int(m.group(1))], part)
        out.append(part)
    return "".join(out)


def _cells(line: str) -> list[str]:
    body = line.strip()[1:-1] if line.strip().endswith("|") else line.strip()[1:]
    cells = re.split(r"(?<!\\)\|", body)
    return [c.strip().replace("\\|", "|") for c in cells]


def markdown_to_html(text: str, root: Path, title: str) -> str:
    """A whole HTML document of the Markdown subset of the report pages; images from root."""
    lines = text.splitlines()
    body: list[str] = []
    paragraph: list[str] = []
    bullets: list[str] = []

    def flush() -> None:
        if paragraph:
            body.append("<p>" + _inline(" ".join(paragraph), root) + "</p>")
            paragraph.clear()
        if bullets:
            body.append("<ul>" + "".join(f"<li>{_inline(b, root)}</li>" for b in bullets) + "</ul>")
            bullets.clear()

    i = 0
    while i < len(lines):
        line = lines[i].rstrip()
        heading = re.match(r"^(#{1,6}) (.*)$", line)
        if not line.strip():
            flush()
        elif heading:
            flush()
            level = len(heading.group(1))
            body.append(f"<h{level}>{_inline(heading.group(2), root)}</h{level}>")
        elif line.startswith("|") and i + 1 < len(lines) and re.match(r"^\|[\s|:-]+\|?$", lines[i + 1]):
            flush()
            head = "".join(f"<th>{_inline(c, root)}</th>" for c in _cells(line))
            rows = []
            i += 2
            while i < len(lines) and lines[i].startswith("|"):
                cells = "".join(f"<td>{_inline(c, root)}</td>" for c in _cells(lines[i]))
                rows.append(f"<tr>{cells}</tr>")
                i += 1
            body.append(f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>")
            continue
        elif (image := _IMAGE_LINE.match(line.strip())) is not None:
            flush()
            body.append(_image(image.group("alt"), image.group("src"), root))
        elif line.startswith("- "):
            if paragraph:
                flush()
            bullets.append(line[2:])
        elif line.startswith("  ") and bullets:
            bullets[-1] += " " + line.strip()
        elif line.startswith("    "):
            flush()
            body.append(f"<pre><code>{html.escape(line.strip())}</code></pre>")
        else:
            if bullets:
                flush()
            paragraph.append(line.strip())
        i += 1
    flush()
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )


def write_html_page(markdown_page: Path, title: str) -> Path:
    """Write NAME.html beside NAME.md (figures embedded); return its path."""
    from ..app.fileio import write_text_atomic

    markdown_page = Path(markdown_page)
    target = markdown_page.with_suffix(".html")
    write_text_atomic(target, markdown_to_html(markdown_page.read_text(), markdown_page.parent, title))
    return target
