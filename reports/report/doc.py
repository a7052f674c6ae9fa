"""The report's document: Markdown and self-contained HTML written side by side by one
:class:`Doc` (headings, paragraphs, tables whose cells may differ between the two, figures
with their alt text and hover lines), and the HTML page's style and script (:data:`CSS`,
:data:`CARDS`: a table of more than seven columns turns into one card per row on a narrow
screen, :data:`SCRIPT`). Markdown tables escape what GitHub-flavoured Markdown would
otherwise read as cell borders; every table is preceded by a one-line title, so that two
reports diff cleanly.
"""

from __future__ import annotations

import base64
import contextlib
import html
import json
import re
from pathlib import Path

from reports.report.canvas import figure_meta
from reports.store.format import fmt, md_cell


def anchor(text: str) -> str:
    """The id GitHub gives a heading: lower case, punctuation other than ``-`` and ``_``
    dropped, spaces as ``-``; the HTML report uses the same ids, so links work in both."""
    text = text.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


class Cell:
    """A table cell: plain text, or Markdown and HTML of its own; ``num``: a number (kept
    on one line, right-aligned); ``cls``: an HTML class (the verdict colours)."""

    def __init__(self, text="", md=None, html_=None, num=False, cls=""):
        self.text = str(text)
        self.md = md
        self.html = html_
        self.num = num
        self.cls = cls

    def to_md(self) -> str:
        return self.md if self.md is not None else md_cell(self.text)

    def to_html(self) -> str:
        return self.html if self.html is not None else html.escape(self.text)


def scenario_link(scenario: str) -> Cell:
    """A scenario's name linking to its details."""
    a = anchor(scenario)
    return Cell(
        md=f"[{md_cell(scenario)}](#{a})",
        html_=f"<a href='#{a}'>{html.escape(scenario).replace('_', '_<wbr>')}</a>",
    )


def nums(values) -> Cell:
    """Several numbers in one cell (one per configuration of a group), each kept whole."""
    texts = [fmt(v) for v in values]
    return Cell(
        " / ".join(texts),
        html_=" / ".join(f"<span>{html.escape(t)}</span>" for t in texts),
        cls="nums",
    )


def num(v, text=None) -> Cell:
    return Cell(fmt(v) if text is None else text, num=True)


def order_cell(text: str) -> Cell:
    """A fitted order with its points (``2.00 (3 pts)``): a number that may wrap before its
    count, so that it does not widen a table of many columns."""
    parts = text.split(" ", 1)
    return Cell(text, html_=" ".join(f"<span>{html.escape(t)}</span>" for t in parts), cls="nums")


class Doc:
    """Markdown and HTML written side by side."""

    def __init__(self):
        self.md: list[str] = []
        self.html: list[str] = []

    def heading(self, level: int, text: str, id_: str | None = None) -> None:
        id_ = id_ or anchor(text)
        self.md.append(f"{'#' * level} {text}\n")
        self.html.append(f"<h{level} id='{html.escape(id_)}'>{html.escape(text)}</h{level}>")

    def para(self, md: str, html_: str | None = None, cls: str = "") -> None:
        self.md.append(md + "\n")
        attr = f" class='{cls}'" if cls else ""
        self.html.append(f"<p{attr}>{html_ if html_ is not None else html.escape(md)}</p>")

    def bullets(self, items: list[tuple[str, str]]) -> None:
        """Items as (Markdown, HTML)."""
        self.md.append("\n".join(f"- {m}" for m, _ in items) + "\n")
        self.html.append("<ul>" + "".join(f"<li>{h}</li>" for _, h in items) + "</ul>")

    def table(self, title: str, header: list, rows: list[list], cls: str = "") -> None:
        """A table with its one-line title; header entries and cells are text or
        :class:`Cell`. In HTML inside a container that scrolls should the table be wider than
        the page; a table of class ``stack`` turns into one card per row on a narrow screen
        (below 1000 px, :data:`CARDS`), each cell labelled with its column (``data-label``);
        so does every table of more than seven columns; one of class ``narrow-stack`` only
        below 640 px."""
        heads = [h if isinstance(h, Cell) else Cell(h) for h in header]
        if len(heads) > 7 and "stack" not in cls.split():
            cls = f"{cls} stack".strip()
        cells = [[c if isinstance(c, Cell) else Cell(c) for c in r] for r in rows]
        md = [f"**{md_cell(title)}**", ""] if title else []
        md.append("| " + " | ".join(h.to_md() for h in heads) + " |")
        # a column of numbers right-aligned, as in HTML
        right = [
            bool(cells) and all(r[k].num for r in cells if k < len(r)) for k in range(len(heads))
        ]
        md.append("|" + "|".join("--:" if a else "---" for a in right) + "|")
        md += ["| " + " | ".join(c.to_md() for c in r) + " |" for r in cells]
        self.md.append("\n".join(md) + "\n")
        head = "".join(f"<th>{h.to_html()}</th>" for h in heads)
        labels = [html.escape(h.text, quote=True) for h in heads]
        body = []
        for r in cells:
            tds = []
            for k, c in enumerate(r):
                classes = " ".join(x for x in ("num" if c.num else "", c.cls) if x)
                attr = f" class='{classes}'" if classes else ""
                if k < len(labels):
                    attr += f" data-label='{labels[k]}'"
                tds.append(f"<td{attr}>{c.to_html()}</td>")
            body.append("<tr>" + "".join(tds) + "</tr>")
        caption = f"<div class='title'>{html.escape(title)}</div>" if title else ""
        self.html.append(
            f"{caption}<div class='scroll'><table class='{cls}'><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table></div>"
        )

    def open_details(self, summary: str, id_: str = "", md: bool = True, open_=False) -> None:
        """A collapsible section (HTML); with ``md`` also in Markdown (GitHub renders it)."""
        attr = (f" id='{html.escape(id_)}'" if id_ else "") + (" open" if open_ else "")
        self.html.append(f"<details{attr}><summary>{summary}</summary>")
        if md:
            self.md.append(f"<details><summary>{html.escape(_strip_tags(summary))}</summary>\n")

    def close_details(self, md: bool = True) -> None:
        self.html.append("</details>")
        if md:
            self.md.append("</details>\n")

    def images(
        self, paths: list[Path], root: Path, cls: str = "plots", md: bool = True, alts=None
    ) -> None:
        """Figures: in Markdown as links to the files, in HTML embedded (base64), each with
        its alt text and, where :func:`reports.report.canvas.figure_meta` has them, the lines a
        pointer over the figure names (``data-lines``, read by :data:`SCRIPT`)."""
        if not paths:
            return
        if md:
            for p in paths:
                alt = (alts or {}).get(p) or figure_meta(p).get("alt") or p.stem
                self.md.append(f"![{_md_alt(alt)}]({p.relative_to(root).as_posix()})\n")
        figs = "".join(figure_html(p, (alts or {}).get(p, "")) for p in paths)
        self.html.append(f"<div class='{cls}'>{figs}</div>")

    def raw_html(self, text: str) -> None:
        self.html.append(text)

    def md_details(self, summary: str) -> None:
        """A collapsible section of report.md only (GitHub renders ``<details>``): the
        HTML report shows the same part open, or collapses it its own way."""
        self.md.append(f"<details><summary>{html.escape(summary)}</summary>\n")

    def md_end(self) -> None:
        self.md.append("</details>\n")

    @contextlib.contextmanager
    def only(self, side: str):
        """Write what the block writes to one side only: ``md`` (report.md) or ``html``."""
        keep_md, keep_html = len(self.md), len(self.html)
        yield self
        if side == "md":
            del self.html[keep_html:]
        else:
            del self.md[keep_md:]


def figure_html(p: Path, alt: str = "") -> str:
    """A figure embedded in the page: the PNG as a data URI, its alt text (``alt``, or the
    one written beside the figure), its hover lines."""
    meta = figure_meta(p)
    alt = alt or meta.get("alt") or p.stem.replace("__", ": ").replace("_", " ")
    data = base64.b64encode(p.read_bytes()).decode()
    lines = meta.get("lines") or []
    hover = ""
    if lines:
        hover = f" data-lines='{html.escape(json.dumps(lines, separators=(',', ':')), quote=True)}'"
    kind = p.stem.rsplit("__", 1)[-1]
    return (
        f"<figure class='fig k-{html.escape(kind)}'{hover}>"
        f"<img alt='{html.escape(alt, quote=True)}' loading='eager' "
        f"src='data:image/png;base64,{data}'><span class='tip' hidden></span></figure>"
    )


def _md_alt(text: str) -> str:
    """Alt text safe inside Markdown's ``![...]``."""
    return " ".join(str(text).split()).replace("[", "(").replace("]", ")")


def _strip_tags(text: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", text))


CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;font-size:15px;
 line-height:1.4;margin:0 auto;max-width:1320px;padding:0 16px 48px;color:#1b1b1b}
h1{font-size:1.6em;margin:.6em 0 .2em} h2{margin-top:1.6em;border-bottom:1px solid #ddd}
h3{display:inline;font-size:1.15em;margin:0}
section.scenario{margin:18px 0 10px;padding-top:6px;border-top:1px solid #eee}
section.scenario .counts{color:#555;font-size:.9em;margin-left:.5em}
.meta{color:#555;font-size:.92em} nav.toc{background:#f6f8fa;padding:6px 10px;margin:10px 0;
 border-radius:6px;font-size:.95em} nav.toc a{margin-right:.6em;white-space:nowrap}
.scroll{overflow-x:auto;max-width:100%;margin:4px 0 14px}
.title{font-weight:600;margin-top:12px}
p.legend,p.hint{font-size:.9em;color:#333} p.legend{background:#f6f8fa;padding:6px 10px;
 border-radius:6px} p.hint{color:#666;margin:2px 0}
table{border-collapse:collapse;font-size:13px}
th{background:#f3f3f3;text-align:left;vertical-align:bottom}
td,th{border:1px solid #d0d7de;padding:3px 7px;vertical-align:top}
td.num{text-align:right;white-space:nowrap;font-variant-numeric:tabular-nums}
table.settings td{overflow-wrap:anywhere}
table.details{font-size:12.5px} table.details td,table.details th{padding:3px 5px}
table.scorecard{font-size:12.5px;width:100%;table-layout:fixed}
table.scorecard th:first-child{width:9.5em}
table.scorecard td{overflow-wrap:break-word} a.entry .fig.wrap{white-space:normal}
a.entry{display:block;margin:2px 0 4px;padding:2px 6px;border-left:4px solid #999;
 border-radius:3px;color:inherit;text-decoration:none}
a.entry .head{display:block} a.entry .fig{white-space:nowrap;font-variant-numeric:tabular-nums}
a.entry .fails{display:block;color:#a50e0e;font-weight:600;font-size:.92em}
a.entry ul.who{list-style:none;margin:1px 0 0;padding:0;font-size:.9em}
a.entry .cost{color:#444;white-space:nowrap;font-variant-numeric:tabular-nums}
abbr{text-decoration:underline dotted;cursor:help}
.v-pass{background:#e6f4ea} a.v-pass{border-left-color:#1e8e3e}
.v-fail{background:#fce8e6} a.v-fail{border-left-color:#d93025}
.v-diverged{background:#f9d6d2} a.v-diverged{border-left-color:#8c1d18}
.v-error{background:#fef7e0} a.v-error{border-left-color:#b06000}
.v-reference-inaccurate{background:#eceff1} a.v-reference-inaccurate{border-left-color:#607d8b}
td.win{background:#eef6ee} small.win{font-weight:600}
table.verdict{font-size:14px} table.verdict td.num{min-width:3.2em}
table.verdict tr:last-child td{border-top:2px solid #8c959f}
td.nums{text-align:right;font-variant-numeric:tabular-nums} td.nums span{white-space:nowrap}
span[class^=v-]{padding:0 4px;border-radius:3px}
details{margin:6px 0} details>summary{cursor:pointer;padding:4px 0;color:#0b57d0}
.plots{display:flex;flex-wrap:wrap;gap:10px;align-items:flex-start;margin:6px 0}
figure.fig{margin:0;position:relative;flex:1 1 520px;max-width:100%}
figure.fig.k-scenario,figure.fig.k-scorecard{flex-basis:100%}
figure.fig img{display:block;max-width:100%;height:auto;border:1px solid #eee}
figure.fig .tip{position:absolute;pointer-events:none;background:#1b1b1b;color:#fff;
 font-size:12px;padding:2px 6px;border-radius:3px;white-space:nowrap;z-index:5}
figure.fig figcaption{font-size:.88em;color:#555}
"""


#: a table of class ``stack`` becomes one card per row, each cell labelled with its column,
#: below 1000 px; one of class ``narrow-stack`` (few columns that wrap) only below 640 px
CARDS = """@media (max-width:WIDTHpx){
 table.CLS,table.CLS tbody,table.CLS tr,table.CLS td{display:block;width:auto}
 table.CLS{border:none} table.CLS thead{display:none}
 table.CLS tr{border:1px solid #d0d7de;border-radius:4px;margin:0 0 8px}
 table.CLS td{border:none;border-bottom:1px solid #eee;text-align:left;white-space:normal;
  min-width:0}
 table.CLS td:empty{display:none}
 table.CLS td::before{content:attr(data-label);display:block;font-size:11px;color:#555;
  font-weight:600}
}
"""


#: opens the collapsed section a link points into (the scorecard links to the details), and
#: names the line under the pointer in a figure (its polylines are the figure's data-lines)
SCRIPT = """
function openTarget(){var id=decodeURIComponent(location.hash.slice(1));if(!id)return;
var el=document.getElementById(id);var t=el;while(el){if(el.tagName==='DETAILS')el.open=true;
el=el.parentElement;}if(t)t.scrollIntoView();}
function segDist(px,py,ax,ay,bx,by){var dx=bx-ax,dy=by-ay,l=dx*dx+dy*dy,u=0;
if(l>0){u=((px-ax)*dx+(py-ay)*dy)/l;u=Math.max(0,Math.min(1,u));}
var x=ax+u*dx-px,y=ay+u*dy-py;return Math.sqrt(x*x+y*y);}
function hover(fig){var lines=JSON.parse(fig.getAttribute('data-lines'));
var img=fig.querySelector('img'),tip=fig.querySelector('.tip');
img.addEventListener('mousemove',function(e){var r=img.getBoundingClientRect();
var px=e.clientX-r.left,py=e.clientY-r.top,best='',bd=1e9;
lines.forEach(function(l){l.paths.forEach(function(p){for(var i=0;i<p.length;i++){
var a=p[i],b=p[Math.min(i+1,p.length-1)];var d=segDist(px,py,a[0]*r.width,a[1]*r.height,
b[0]*r.width,b[1]*r.height);if(d<bd){bd=d;best=l.label;}}});});
if(best&&bd<7){tip.textContent=best;tip.hidden=false;var left=px+14;
if(left+tip.offsetWidth>r.width)left=Math.max(0,px-14-tip.offsetWidth);
tip.style.left=left+'px';tip.style.top=(py+12)+'px';}else{tip.hidden=true;}});
img.addEventListener('mouseleave',function(){tip.hidden=true;});}
window.addEventListener('hashchange',openTarget);
document.addEventListener('DOMContentLoaded',function(){
document.querySelectorAll('figure[data-lines]').forEach(hover);openTarget();});
"""
