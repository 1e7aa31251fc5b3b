"""``terradyn reproduce``: verdicts computed from the run, the cache, the CLI edges, and the
page in a real browser (headless Chromium, Debian package `chromium`, installed by .ci/run)."""
from __future__ import annotations

import json
import re
import shutil

import pytest

from terradyn.cli import main
from terradyn.report import PART_NAMES, card_verdict, judge, reproduce
from terradyn.report import parts as P
from terradyn.report import run as R

CHROMIUM = shutil.which("chromium")
VERDICTS = {"matches", "differs", "no published number"}


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    return out, reproduce(out, "quick")


def test_judge_reads_the_tolerance_and_the_numbers():
    assert judge(1.04, 1.0, "within 5 %") is True and judge(1.06, 1.0, "within 5 %") is False
    assert judge(9.4, 5.3, "within +-5 points") is True and judge(10.4, 5.3, "within +-5 points") is False
    assert judge(4, 4, "exact") is True and judge(8, 4, "exact") is False
    assert judge(0.02, 0.05, "<= reference") is True and judge(0.5, 0.4, "<= RFT's") is False
    assert judge(-0.1, None, "< 0") is True and judge(0.1, None, "< 0") is False
    assert judge(0.96, None, ">= 0.95") is True and judge(2.0, None, "> 1.5") is True
    assert judge(1.0, None, None) is None and judge(1.0, None, "within 5 %") is None
    assert judge(float("nan"), 1.0, "within 5 %") is None
    with pytest.raises(ValueError):
        judge(1.0, 1.0, "roughly")
    assert card_verdict([True, None]) == "matches" and card_verdict([True, False]) == "differs"
    assert card_verdict([None, None]) == "no published number"


def test_every_shipped_sph_result_file_loads(tmp_path):
    """Every file the report reads as an SPH validation result is one (a study's JSON under a
    validation's name once broke the report); anything else is refused by name."""
    files = P.sph_result_files()
    assert files, "no shipped SPH result files found"
    results = P.load_sph_results(files)
    assert all(r["checks"] and all({"scene", "quantity", "ours"} <= set(c) for c in r["checks"]) for r in results)
    stray = tmp_path / "sph_validate_study.json"
    stray.write_text(json.dumps({"what": "a study", "legs": {}}))
    with pytest.raises(ValueError, match="sph_validate_study.json: not an SPH validation result"):
        P.load_sph_results([stray])


def test_every_claim_has_a_verdict_computed_from_its_numbers(quick_report):
    out, rep = quick_report
    disk = json.loads((out / "report.json").read_text())
    assert disk["summary"] == rep["summary"]
    assert [p["name"] for p in disk["parts"]] == list(PART_NAMES)
    ids = [c["id"] for p in disk["parts"] for c in p["cards"]]
    for want in ("interp-holdout", "legs-flat", "legs-c", "legs-reverse-c", "legs-closed-forms", "rft-vs-sph",
                 "rft-sph-experiment", "rft-vs-s12", "foot-lengths", "foot-trials", "dddas-ranks", "dddas-cv-flat", "dddas-pf-flat", "dddas-speed",
                 "dddas-foot", "sph-bed", "sph-plate", "sph-rig", "sph-legs"):
        assert want in ids
    assert len(disk["claims"]) == disk["summary"]["n_claims"] > 50
    for c in disk["claims"]:
        assert c["verdict"] in VERDICTS
        tol = None if c["tolerance"].startswith("none") else c["tolerance"]
        # the stored verdict is the tolerance rule applied to the stored numbers
        assert judge(c["ours"], c["reference"], tol) == c["passed"], c
        assert (c["verdict"] == "no published number") == (c["passed"] is None)
        assert c["source"]
    for p in disk["parts"]:
        for card in p["cards"]:
            assert card["statement"] and card["source"] and card["figures"]
            assert card["verdict"] == card_verdict([c["passed"] for c in card["claims"]])
    prov = disk["provenance"]
    assert set(prov["parts"]) >= set(PART_NAMES) and prov["versions"]["numpy"] and prov["seeds"]


def test_a_verdict_follows_the_run_not_a_constant(tmp_path, monkeypatch):
    """Feed the foot part forces that fall with length: 'grows with length' must differ."""
    from terradyn import studies

    real = studies.foot_study

    def shrinking(out, **kw):
        s = real(out, **kw)
        s["Fz_at_max_N"] = s["Fz_at_max_N"][::-1]
        return s

    ok = {c.quantity: c.passed for card in P.foot_part(tmp_path / "a", {"n_theta": 11}) for c in card.checks}
    monkeypatch.setattr(studies, "foot_study", shrinking)
    bad = {c.quantity: c.passed for card in P.foot_part(tmp_path / "b", {"n_theta": 11}) for c in card.checks}
    q = next(k for k in ok if k.startswith("smallest increase of Fz"))
    assert ok[q] is True and bad[q] is False


def test_parts_are_cached_by_their_inputs(tmp_path, monkeypatch):
    first = reproduce(tmp_path, "quick", parts=["foot"])
    again = reproduce(tmp_path, "quick", parts=["foot"])
    assert not first["provenance"]["parts"]["foot"]["cached"] and again["provenance"]["parts"]["foot"]["cached"]
    base = R.tier_settings

    def changed(tier):
        s = base(tier)
        s["foot"]["n_theta"] = 21
        return s

    monkeypatch.setattr(R, "tier_settings", changed)
    third = reproduce(tmp_path, "quick", parts=["foot"])
    assert not third["provenance"]["parts"]["foot"]["cached"]


def test_cli_edges(tmp_path, capsys):
    assert main(["reproduce", "--quick", "--full", "--out", str(tmp_path)]) == 2
    assert main(["reproduce", "--quick", "--part", "nope", "--out", str(tmp_path)]) == 2
    assert main(["reproduce", "--quick", "--regenerate", "--out", str(tmp_path)]) == 2
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["reproduce", "--quick", "--out", str(f)]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_page_is_self_contained(quick_report):
    out, rep = quick_report
    html = (out / "index.html").read_text()
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", html)
    assert "url(" not in html and "<script" not in html
    assert html.count('class="card"') == rep["summary"]["n_cards"]
    assert 'name="viewport"' in html and "@media print" in html


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed here (.ci/run installs it in CI)")
def test_page_in_a_real_browser(quick_report, tmp_path):
    from playwright.sync_api import sync_playwright

    out, rep = quick_report
    ids = [c["id"] for p in rep["parts"] for c in p["cards"]]
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync"]
    errors = []
    with sync_playwright() as pw:
        ctx = pw.chromium.launch_persistent_context(str(tmp_path / "profile"), executable_path=CHROMIUM,
                                                    headless=True, args=flags, viewport={"width": 1200, "height": 900})
        ctx.set_default_timeout(60_000)
        page = ctx.new_page()
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto((out / "index.html").resolve().as_uri(), wait_until="load")
        page.wait_for_function("[...document.images].every(i => i.complete)")
        found = page.eval_on_selector_all("article.card", "els => els.map(e => e.id)")
        assert found == ids
        broken = page.eval_on_selector_all("img", "els => els.filter(i => !i.complete || i.naturalWidth === 0).length")
        n_img = page.eval_on_selector_all("img", "els => els.length")
        assert n_img >= len(ids) and broken == 0
        assert page.locator("#summary").is_visible() and page.locator("#provenance").is_visible()
        shot = tmp_path / "report.png"
        page.screenshot(path=str(shot), full_page=False)
        assert shot.stat().st_size > 10_000
        page.set_viewport_size({"width": 390, "height": 844})  # a phone: nothing wider than the screen
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth + 1")
        ctx.close()
    assert errors == []


def test_full_tier_judges_a_fresh_validation_run(tmp_path, monkeypatch):
    """The full tier's plumbing, with the SPH validation (hours) replaced by a stand-in
    returning one bed check: its verdict is judged from its numbers and the run is cached."""
    from terradyn.sph import suite

    calls = []

    def fake_validate(**kw):
        calls.append(kw)
        kw["figures_dir"].joinpath("bed.png").write_bytes((tmp_path / "x.png").read_bytes())
        return {"checks": [suite.Check("bed", "d(-sigma_zz)/d(depth) / (rho g)", 1.3, 1.0, "analytic",
                                       "within 5 %", True).describe()], "settings": {}}

    from terradyn.plots import _save, plt

    fig = plt.figure(figsize=(1, 1))
    _save(fig, tmp_path / "x.png")
    plt.close(fig)
    monkeypatch.setattr(suite, "validate", fake_validate)
    rep = reproduce(tmp_path / "r", "full", parts=["sph"])
    assert calls[0]["store"].is_relative_to(tmp_path / "r" / "parts")  # leg runs kept: an interrupted run resumes
    (card,) = rep["parts"][0]["cards"]
    assert card["id"] == "sph-bed" and card["figures"] == ["bed.png"]
    assert card["claims"][0]["verdict"] == "differs"  # 1.3 is not within 5 % of 1: the stored "pass" is not trusted
    again = reproduce(tmp_path / "r", "full", parts=["sph"])
    assert len(calls) == 1 and again["provenance"]["parts"]["sph-run"]["cached"]
