"""The report as one self-contained HTML page: figures embedded (base64 PNG), inline CSS, no
script and no external resource; readable on a phone (fluid layout, scrolling tables) and in
print (cards kept whole, no shadows)."""
from __future__ import annotations

import base64
from html import escape
from pathlib import Path

from ..io import atomic_write_text

CSS = """
:root{--ok:#1e7b34;--bad:#b3261e;--none:#5f6368;--ink:#1f2328;--muted:#57606a;--line:#d0d7de;--card:#fff;--bg:#f6f8fa}
*{box-sizing:border-box}
body{margin:0;overflow-wrap:anywhere;font:15px/1.5 system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;color:var(--ink);background:var(--bg)}
main{max-width:1100px;margin:0 auto;padding:1rem}
h1{font-size:1.6rem;margin:.5rem 0}
h2{font-size:1.25rem;margin:2rem 0 .5rem;border-bottom:2px solid var(--line);padding-bottom:.2rem}
h3{font-size:1.05rem;margin:0 0 .4rem}
.lede{color:var(--muted)}
.card{background:var(--card);border:1px solid var(--line);border-radius:8px;padding:1rem;margin:1rem 0;box-shadow:0 1px 3px rgba(0,0,0,.06)}
.card header{display:flex;flex-wrap:wrap;gap:.5rem;align-items:baseline;justify-content:space-between}
.verdict{display:inline-block;font-weight:600;font-size:.85rem;padding:.1rem .55rem;border-radius:1rem;color:#fff;white-space:nowrap}
.v-matches{background:var(--ok)}.v-differs{background:var(--bad)}.v-none{background:var(--none)}
figure{margin:.6rem 0}
figure img{display:block;max-width:100%;height:auto;border:1px solid var(--line);border-radius:4px;background:#fff}
figcaption{font-size:.8rem;color:var(--muted)}
blockquote{margin:.6rem 0;padding:.4rem .8rem;border-left:4px solid #8c959f;background:#f3f4f6}
cite{display:block;font-size:.8rem;color:var(--muted);font-style:normal;margin-top:.2rem}
.note{font-size:.85rem;color:var(--muted)}
.scroll{overflow-x:auto;-webkit-overflow-scrolling:touch}
table{border-collapse:collapse;width:100%;font-size:.85rem;margin:.5rem 0;overflow-wrap:normal}
th,td{border:1px solid var(--line);padding:.25rem .45rem;text-align:left;vertical-align:top}
th{background:#eef1f4;white-space:nowrap}
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
.missing{padding:1rem;border:1px dashed var(--bad);color:var(--bad)}
footer{margin-top:2rem;font-size:.85rem;color:var(--muted)}
@media (max-width:640px){body{font-size:14px}main{padding:.5rem}.card{padding:.6rem}h1{font-size:1.3rem}}
@media print{body{background:#fff;font-size:11pt}main{max-width:none;padding:0}
.card{box-shadow:none;break-inside:avoid;page-break-inside:avoid}.verdict{border:1px solid #000;color:#000;background:none!important}
a{color:inherit;text-decoration:none}h2{break-after:avoid}.scroll{overflow:visible}}
"""

_VCLASS = {"matches": "v-matches", "differs": "v-differs", "no published number": "v-none"}


def _e(x) -> str:
    return escape("" if x is None else str(x))


def _num(v) -> str:
    if v is None:
        return "&mdash;"
    if isinstance(v, float):
        return _e(f"{v:.4g}")
    return _e(v)


def _badge(verdict: str) -> str:
    return f'<span class="verdict {_VCLASS.get(verdict, "v-none")}">{_e(verdict)}</span>'


def _figure(path: Path, caption: str) -> str:
    if not path.is_file():
        return f'<div class="missing">figure not produced: {_e(path.name)}</div>'
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return (f'<figure><img src="data:image/png;base64,{data}" alt="{_e(caption)}">'
            f"<figcaption>{_e(caption)}</figcaption></figure>")


def _claims_table(rows: list[dict]) -> str:
    head = ("<tr><th>quantity</th><th>ours</th><th>published</th><th>unit</th><th>tolerance</th>"
            "<th>verdict</th></tr>")
    body = "".join(
        f"<tr><td>{_e(r['quantity'])}</td><td class=num>{_num(r['ours'])}</td>"
        f"<td class=num>{_num(r['reference']) if r['reference'] is not None else 'none'}</td><td>{_e(r['unit'])}</td>"
        f"<td>{_e(r['tolerance'])}</td><td>{_badge(r['verdict'])}</td></tr>" for r in rows)
    return f'<div class="scroll"><table class="claims">{head}{body}</table></div>'


def _extra_table(rows: list[dict]) -> str:
    if not rows:
        return ""
    cols = list(dict.fromkeys(k for r in rows for k in r))
    head = "".join(f"<th>{_e(c)}</th>" for c in cols)
    body = "".join("<tr>" + "".join(
        f"<td class=num>{_num(r.get(c))}</td>" if isinstance(r.get(c), (int, float)) else f"<td>{_e(r.get(c))}</td>"
        for c in cols) + "</tr>" for r in rows)
    return f'<details><summary>numbers</summary><div class="scroll"><table>{"<tr>" + head + "</tr>"}{body}</table></div></details>'


def _card(card: dict, folder: Path) -> str:
    figs = "".join(_figure(folder / f, f"{card['title']}: {Path(f).name}") for f in card["figures"])
    note = f'<p class="note">{_e(card["note"])}</p>' if card.get("note") else ""
    return (f'<article class="card" id="{_e(card["id"])}" data-verdict="{_e(card["verdict"])}">'
            f'<header><h3>{_e(card["title"])}</h3>{_badge(card["verdict"])}</header>'
            f'{figs}<blockquote>{_e(card["statement"])}<cite>Source: {_e(card["source"])}</cite></blockquote>'
            f'{_claims_table(card["claims"])}{note}{_extra_table(card.get("table", []))}</article>')


def _summary(report: dict) -> str:
    rows = []
    for p in report["parts"]:
        for c in p["cards"]:
            n = {}
            for r in c["claims"]:
                n[r["verdict"]] = n.get(r["verdict"], 0) + 1
            counts = ", ".join(f"{v} {k}" for k, v in n.items())
            rows.append(f'<tr><td>{_e(p["title"])}</td><td><a href="#{_e(c["id"])}">{_e(c["title"])}</a></td>'
                        f"<td>{_badge(c['verdict'])}</td><td>{_e(counts)}</td></tr>")
    return ('<div class="scroll"><table id="summary"><tr><th>part</th><th>claim</th><th>verdict</th>'
            f'<th>rows</th></tr>{"".join(rows)}</table></div>')


def _provenance(prov: dict) -> str:
    vers = ", ".join(f"{k} {v}" for k, v in prov["versions"].items() if v)
    m = prov["machine"]
    times = "".join(f"<tr><td>{_e(k)}</td><td class=num>{v['seconds']:.1f} s</td>"
                    f"<td>{'cached' if v.get('cached') else 'run'}</td></tr>" for k, v in prov["parts"].items())
    seeds = ", ".join(f"{k}: {v}" for k, v in prov["seeds"].items())
    return (f"<footer id=\"provenance\"><h2>Provenance</h2><ul>"
            f"<li>git commit: {_e(prov['git_commit'] or 'not a git checkout')}</li>"
            f"<li>tier: {_e(prov['tier'])}; created {_e(prov['created'])}; total {prov['total_seconds']:.1f} s</li>"
            f"<li>packages: Python {_e(prov['python'])}, {_e(vers)}</li>"
            f"<li>machine: {_e(m['platform'])}, {_e(m['processor'])}, {_e(m['cpus'])} CPUs</li>"
            f"<li>seeds: {_e(seeds)}</li><li>SPH validation numbers: {_e(prov['sph_results'])}</li>"
            f"<li>SPH training set: {_e(prov['sph_dataset'] or 'not found')}</li></ul>"
            f'<div class="scroll"><table><tr><th>part</th><th>run time</th><th>this run</th></tr>{times}</table></div>'
            "</footer>")


def render(report: dict, out: Path) -> str:
    """The page as a string; figures are read from ``out/parts/<part>/``."""
    s = report["summary"]
    counts = ", ".join(f"{v} {k}" for k, v in s["cards"].items())
    rcounts = ", ".join(f"{v} {k}" for k, v in s["claims"].items())
    body = []
    for p in report["parts"]:
        folder = Path(out) / "parts" / p["name"]
        body.append(f'<section id="part-{_e(p["name"])}"><h2>{_e(p["title"])}</h2>'
                    + "".join(_card(c, folder) for c in p["cards"]) + "</section>")
    return ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>{_e(report['title'])}</title><style>{CSS}</style></head><body><main>"
            f"<h1>{_e(report['title'])}</h1>"
            f'<p class="lede">Each card sets one published statement (the thesis or Li 2013, as quoted in the '
            f"project's brief) beside what terradyn computes now, with the tolerance and a verdict computed from "
            f"this run. Tier: <b>{_e(report['tier'])}</b>. {s['n_cards']} claims ({_e(counts)}); "
            f"{s['n_claims']} rows ({_e(rcounts)}).</p>"
            f"<h2>Summary</h2>{_summary(report)}{''.join(body)}{_provenance(report['provenance'])}"
            "</main></body></html>\n")


def write(report: dict, out) -> Path:
    return atomic_write_text(Path(out) / "index.html", render(report, Path(out)))
