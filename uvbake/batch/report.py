"""The batch's static HTML report: one page plus the thumbnails already beside the outputs, no server.

Every asset is a table row with its preview render, atlas image, status, validity, charts, distortion,
packing, times and worker; failures come first. Clicking a column header sorts by it (again: reverse);
a text box and a status menu filter the rows. The script is inline and small (hand-written: the page
must open from disk with no network, so no library is fetched).

Self-test: opened as ``report.html?selftest=1`` the page, once loaded, checks that every image decoded,
clicks the "charts" header twice and writes what it saw as JSON into ``<pre id="selftest">``
(row order before and after each click, images decoded / total, the broken ones), which a headless
browser's ``--dump-dom`` reads back (see tests/test_batch_report.py).
"""

from __future__ import annotations

import html
import json
import math
import os
from pathlib import Path
from typing import Any
from urllib.parse import quote

#: (header, row key, kind) of the table's data columns; kind "num" sorts numerically
COLUMNS = [
    ("status", "status", "text"), ("asset", "asset", "text"), ("valid", "valid", "text"),
    ("charts", "charts", "num"), ("angle dist.", "angle_distortion", "num"),
    ("area dist.", "area_distortion", "num"), ("packing", "packing", "num"),
    ("triangles", "triangles", "num"), ("time (s)", "t_asset_s", "num"), ("worker", "worker", "text"),
    ("error", "error", "text"),
]

_CSS = """
body{font:13px/1.35 system-ui,sans-serif;margin:1em;color:#222}
table{border-collapse:collapse}th,td{border-bottom:1px solid #ddd;padding:3px 6px;text-align:left;vertical-align:middle}
th{cursor:pointer;background:#f3f3f3;position:sticky;top:0}th.asc:after{content:" \\25b2"}th.desc:after{content:" \\25bc"}
td.num{text-align:right;font-variant-numeric:tabular-nums}img{display:block;image-rendering:auto}
tr.bad td{background:#fff0f0}.s-done,.s-cached{color:#176e2a}.s-failed,.s-timeout,.s-crashed,.s-lost,.s-invalid{color:#b00020;font-weight:600}
td.err{max-width:28em;font-size:12px;color:#b00020}#bar{margin:.5em 0}
"""

_JS = r"""
(function(){
const tbody=document.querySelector('#assets tbody');
const heads=[...document.querySelectorAll('#assets th[data-key]')];
function val(tr,key,kind){const td=tr.querySelector('td[data-key="'+key+'"]');const v=td?td.dataset.v:'';
  if(kind==='num'){const x=parseFloat(v);return isNaN(x)?Infinity:x;}return v||'';}
function sortBy(th){const dir=th.classList.contains('asc')?-1:1;heads.forEach(h=>h.classList.remove('asc','desc'));
  th.classList.add(dir>0?'asc':'desc');const key=th.dataset.key,kind=th.dataset.kind;
  const rows=[...tbody.rows];rows.sort((a,b)=>{const x=val(a,key,kind),y=val(b,key,kind);
    if(x<y)return -dir;if(x>y)return dir;return (+a.dataset.order)-(+b.dataset.order);});
  rows.forEach(r=>tbody.appendChild(r));}
heads.forEach(th=>th.addEventListener('click',()=>sortBy(th)));
const q=document.getElementById('q'),st=document.getElementById('st');
function filter(){const t=q.value.toLowerCase(),s=st.value;let n=0;
  for(const r of tbody.rows){const ok=(!t||r.textContent.toLowerCase().includes(t))&&(!s||(s==='fail'?r.classList.contains('bad'):r.dataset.status===s));
    r.style.display=ok?'':'none';n+=ok;}document.getElementById('shown').textContent=n;}
q.addEventListener('input',filter);st.addEventListener('change',filter);
function order(){return [...tbody.rows].map(r=>r.dataset.asset);}
if(location.search.includes('selftest=1')){window.addEventListener('load',()=>{
  const imgs=[...document.images];const broken=imgs.filter(i=>!(i.complete&&i.naturalWidth>0)).map(i=>i.getAttribute('src'));
  const res={initial:order(),images_total:imgs.length,images_ok:imgs.length-broken.length,broken:broken};
  const th=document.querySelector('#assets th[data-key="charts"]');th.click();res.charts_asc=order();
  th.click();res.charts_desc=order();
  q.value='zzz-no-such-asset';filter();res.shown_after_filter=+document.getElementById('shown').textContent;q.value='';filter();
  document.getElementById('selftest').textContent=JSON.stringify(res);});}
})();
"""


def write_report(path: str | os.PathLike[str], rows: list[dict[str, Any]],
                 out_dir: str | os.PathLike[str]) -> Path:
    """Write the report for ``rows`` (summary rows, failures first) to ``path``, atomically."""
    from uvbake.io.atomic import atomic_write

    out_dir = Path(out_dir)
    n_bad = sum(r["status"] not in ("done", "cached") for r in rows)
    statuses = sorted({r["status"] for r in rows})
    head = "".join(f'<th data-key="{k}" data-kind="{kind}">{html.escape(h)}</th>'
                   for h, k, kind in COLUMNS[:2]) + "<th>preview</th><th>atlas</th>" + \
        "".join(f'<th data-key="{k}" data-kind="{kind}">{html.escape(h)}</th>' for h, k, kind in COLUMNS[2:])
    body = "\n".join(_row(i, r, out_dir) for i, r in enumerate(rows))
    options = "".join(f'<option value="{html.escape(s)}">{html.escape(s)}</option>' for s in statuses)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>uvbake batch report</title><style>{_CSS}</style></head>
<body><h1>uvbake batch</h1>
<p>{len(rows)} assets: {len(rows) - n_bad} done or cached, <b>{n_bad} failed</b>. Summary: <a href="summary.csv">summary.csv</a>, summary.parquet.</p>
<div id="bar">filter <input id="q" type="search" placeholder="name or error">
status <select id="st"><option value="">all</option><option value="fail">any failure</option>{options}</select>
showing <span id="shown">{len(rows)}</span></div>
<table id="assets"><thead><tr>{head}</tr></thead><tbody>
{body}
</tbody></table><pre id="selftest"></pre>
<script>{_JS}</script></body></html>
"""
    with atomic_write(path) as fh:
        fh.write(page)
    return Path(path)


def _row(i, r, out_dir):
    bad = r["status"] not in ("done", "cached")
    cells = [_cell(r, *c) for c in COLUMNS]
    imgs = [_img(r, which, out_dir) for which in ("preview", "atlas")]
    cells = cells[:2] + imgs + cells[2:]
    return (f'<tr data-asset="{html.escape(r["asset"])}" data-status="{html.escape(r["status"])}" data-order="{i}"'
            f'{" class=bad" if bad else ""}>' + "".join(cells) + "</tr>")


def _cell(r, header, key, kind):
    v = r.get(key)
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return f'<td data-key="{key}" data-v=""></td>'
    if kind == "num":
        text = f"{100 * v:.1f}%" if key == "packing" else (f"{v:,}" if isinstance(v, int) else f"{v:.3g}")
        return f'<td class="num" data-key="{key}" data-v="{v!r}">{text}</td>'
    text = ("yes" if v else "NO") if isinstance(v, bool) else str(v)
    cls = f' class="s-{html.escape(text)}"' if key == "status" else (' class="err"' if key == "error" else "")
    return f'<td{cls} data-key="{key}" data-v="{html.escape(text)}">{html.escape(text)}</td>'


def _img(r, which, out_dir):
    name = r.get(which)
    if not name:
        return "<td></td>"
    src = "assets/" + quote(r["asset"]) + "/" + quote(name)
    if not (out_dir / "assets" / r["asset"] / name).exists():
        return "<td></td>"
    return f'<td><a href="{src}"><img src="{src}" alt="{which} of {html.escape(r["asset"])}" loading="eager" height="72"></a></td>'


def selftest_result(dom: str) -> dict:
    """The JSON the self-test wrote into a dumped DOM."""
    start = dom.index('<pre id="selftest">') + len('<pre id="selftest">')
    return json.loads(html.unescape(dom[start:dom.index("</pre>", start)]))
