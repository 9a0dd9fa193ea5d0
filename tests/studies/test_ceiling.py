"""The study of what planning for the lowest breakaway reaches when the table is known."""

from __future__ import annotations

import pytest

from papwc_studies import ceiling

#: Table 1 with random stiction only: the closed form, quick to step.
STICTION = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0, "f_s_spread": 0.15,
            "seed": 3}
#: With a lag of 4 ms as well (integrated).
LAG = {**STICTION, "tau_u": 4e-3}


def test_known_table_is_reached_and_no_pulse_moves_beyond_the_error():
    done = ceiling.Approach(STICTION).run()
    assert done.error <= 1e-6
    assert done.pulses == len(done.record) >= 1
    assert ceiling.beyond(done.record, True)[1] == 0
    # planned for the lowest breakaway still possible, a pulse moves at most |e|
    for e, d in done.record:
        assert d * e >= 0.0
        assert abs(d) <= abs(e) * (1.0 + 1e-9)


def test_the_proof_is_the_least_breakaway_at_which_the_height_does_not_move():
    approach = ceiling.Approach(STICTION)
    state = approach.table.state()
    low = approach.lowest
    b = approach.proof(state, 140.0, low)
    assert low < b <= 140.0 + (approach.highest - low) / 2**ceiling.STEPS
    assert approach.move(state, b, 140.0) == 0.0
    assert approach.move(state, b - 0.01, 140.0) > 0.0


def test_a_model_without_the_lag_plans_lower_pulses_and_needs_more_of_them():
    known = ceiling.Approach(LAG).run(budget=1.0)
    blind = ceiling.Approach(LAG, ceiling.Model("no lag", told={"tau_u": 0.0})).run(budget=1.0)
    assert known.error <= 1e-6 and known.pulses >= 2
    assert all(abs(d) <= abs(e) * (1.0 + 1e-9) for e, d in known.record)
    assert blind.pulses > known.pulses
    assert ceiling.beyond(blind.record, True)[1] == 0


def test_a_model_that_breaks_the_rules_of_the_plant_is_refused():
    with pytest.raises(ValueError, match="the model"):
        ceiling.Approach(STICTION, ceiling.Model("bad", told={"f_c": -1.0}))


def test_the_tables_are_the_distinct_rigid_draws_of_each_file():
    stick_slip = ceiling.tables("realism_mc_fresh.toml")
    lugre = ceiling.tables("realism_mc_lugre_fresh.toml")
    assert len(stick_slip) == 30  # 15 draws x 2 seeds; the three targets share them
    assert len(lugre) == 18
    assert all(0.0 <= p["f_s_spread"] <= 0.15 and "sigma_0" not in p for p in stick_slip)
    assert all(p["sigma_0"] > 0.0 for p in lugre)


def test_a_model_takes_fields_told_and_scales_others():
    model = ceiling.Model("m", told={"f_c": 80.0}, scale={"v_s": 1.25, "tau_u": 0.5})
    table = {**LAG, "v_s": 2e-3}
    assert model.params(table) == {**table, "f_c": 80.0, "v_s": 2.5e-3, "tau_u": 2e-3}
    assert ceiling.MODELS[0].params(table) == table


def test_runaways_are_counted_above_and_below_one_micrometre():
    record = [(5e-6, 4e-6), (5e-6, 8e-6), (-2e-6, -3.2e-6), (5e-7, 2e-6), (5e-7, 0.0),
              (-6e-7, -8e-7)]
    # moving pulses at |e| >= 1 um: 3, of which 5 um -> 8 um and -2 um -> -3.2 um ran away
    assert ceiling.beyond(record, True) == (3, 2, 8e-6)
    # below: 0.5 um -> 2 um ran away; the pulse that did not move is not counted
    assert ceiling.beyond(record, False) == (2, 1, 2e-6)


#: Stribeck friction and random stiction: a pulse just above the breakaway creeps.
STRIBECK = {**STICTION, "v_s": 4e-3, "seed": 6}


def test_a_creep_not_seen_breaks_the_proof_and_the_guard_keeps_the_bound():
    seen = ceiling.Approach(STRIBECK).run(e0=1e-5, budget=1.0)
    unseen = ceiling.Approach(STRIBECK, ceiling.Model("u", unseen=ceiling.MOVED)).run(
        e0=1e-5, budget=1.0)
    guarded = ceiling.Approach(STRIBECK, ceiling.Model("g", unseen=ceiling.MOVED,
                                                        guard=True)).run(e0=1e-5, budget=1.0)
    # seeing every stick anew, the planner keeps the bound
    assert seen.error <= 1e-6
    assert ceiling.beyond(seen.record, True)[1] == 0
    # a creep below 50 nm taken for none: the next pulse, planned above a proof that no
    # longer holds, moves the table beyond 1.5*|e| plus a count
    assert ceiling.beyond(unseen.record, True)[1] >= 1
    # and the approach counts it: each runaway at |e| >= 1 um came after a pulse taken for
    # held that had moved the table; seeing every move, no pulse is taken for held wrongly
    assert len(unseen.broken_before) == len(unseen.record)
    assert 1 <= unseen.moved_unseen <= unseen.taken_held
    runaways = [broken for (e, d), broken
                in zip(unseen.record, unseen.broken_before, strict=True)
                if abs(e) >= 1e-6 and ceiling.runaway(e, d)]
    assert runaways and all(runaways)
    assert seen.moved_unseen == 0 and not any(seen.broken_before)
    # guarded, no pulse passes the bound, and this approach still ends within 1 um
    for far in (True, False):
        assert ceiling.beyond(guarded.record, far)[1] == 0
    assert guarded.error <= 1e-6


def test_through_its_encoder_the_known_table_is_reached_only_by_a_pulse_beyond_the_bound():
    # table 11 of realism_mc_fresh.toml (0.13 um of noise on its 0.1 um encoder), the
    # planner told the table: rows 22 and 23 of the study
    table = ceiling.tables("realism_mc_fresh.toml")[10]
    bet = ceiling.Approach(table, ceiling.MODELS[21]).run()
    guarded = ceiling.Approach(table, ceiling.MODELS[22]).run()
    assert ceiling.MODELS[21].encoder and not ceiling.MODELS[21].guard
    assert ceiling.MODELS[22].encoder and ceiling.MODELS[22].guard
    # climbing past the proofs of pulses it read as held reaches 1 um, but a creep the
    # noise hid had redrawn the breakaway: a pulse at |e| >= 1 um went beyond the bound
    assert bet.error <= 1e-6
    runaways = [broken for (e, d), broken in zip(bet.record, bet.broken_before, strict=True)
                if abs(e) >= 1e-6 and ceiling.runaway(e, d)]
    assert runaways and all(runaways)
    # never betting on a proof, no pulse passes the bound, and the table is not reached
    for far in (True, False):
        assert ceiling.beyond(guarded.record, far)[1] == 0
    assert guarded.error > 1e-6


def test_a_planner_learning_the_lag_keeps_the_table_among_its_candidates():
    learner = ceiling.Approach(LAG, ceiling.Model("lag learned", learn=("tau_u",)))
    assert len(learner.alive) == len(ceiling.GRIDS["tau_u"])
    done = learner.run(budget=1.0)
    assert done.error <= 1e-6
    for far in (True, False):
        assert ceiling.beyond(done.record, far)[1] == 0
    # the pulses ruled lags out, never the table's own (4 ms, on the grid)
    table = (ceiling.GRIDS["tau_u"].index(4e-3),)
    assert table in done.alive
    assert len(done.alive) < len(ceiling.GRIDS["tau_u"])
    # it plans on the shortest lag left: never longer than the table's
    assert done.corner() is done.candidate((min(k[0] for k in done.alive),))
    assert min(k[0] for k in done.alive) <= table[0]


def test_not_told_the_band_only_the_first_reading_rules_out_a_table_without_lag():
    moves_only = ceiling.Approach(LAG, ceiling.Model("m", learn=("tau_u",), band=False))
    first = ceiling.Approach(LAG, ceiling.Model("f", learn=("tau_u",), band=False, first=True))
    # not told f_s and its spread, the planner starts from the sliding friction
    assert moves_only.lowest == first.lowest == LAG["f_c"]
    assert moves_only.highest == ceiling.F_P_MAX
    moves_only.run(budget=0.6)
    first.run(budget=0.6)
    table = ceiling.GRIDS["tau_u"].index(4e-3)
    for done in (moves_only, first):
        assert (table,) in done.alive
        for far in (True, False):
            assert ceiling.beyond(done.record, far)[1] == 0
    # from the moves alone every lag up to the table's stays possible, none included: a
    # breakaway placed higher explains every move
    assert {k[0] for k in moves_only.alive} == set(range(table + 1))
    # the reading one sample after each pulse tells how fast the force rose: only lags
    # near the table's are left, and the approach ends sooner and nearer
    assert min(k[0] for k in first.alive) >= table - 2
    assert first.pulses < moves_only.pulses
    assert first.error < moves_only.error <= 1e-6


def test_through_a_noisy_encoder_the_first_reading_still_rules_out_no_lag():
    noisy = {**LAG, "noise_std": 2e-7, "x_resolution": 1e-7}
    done = ceiling.Approach(noisy, ceiling.Model("e", learn=("tau_u",), band=False,
                                                 first=True, encoder=True)).run(budget=0.6)
    # the slack of a move and of a first reading: three standard deviations and a count
    assert done.slack_d == pytest.approx(3.0 * 2e-7 * (2.0 / ceiling.REST_READS) ** 0.5 + 1e-7)
    assert done.slack_first > done.slack_d
    table = ceiling.GRIDS["tau_u"].index(4e-3)
    assert (table,) in done.alive and (0,) not in done.alive
    assert done.error <= 1e-6
    for far in (True, False):
        assert ceiling.beyond(done.record, far)[1] == 0


def test_the_first_reading_of_a_pulse_through_a_lag_is_a_small_part_of_its_move():
    for tau, share in ((0.0, 0.5), (4e-3, 0.3)):
        plant = ceiling.Plant({**LAG, "tau_u": tau})
        plant.f_s_now = 130.0
        first, d = ceiling.pulse_path(plant, 200.0)
        assert 0.0 < first < d
        # without lag most of the move is done by the first reading, with 4 ms little of it
        assert (first / d > share) == (tau == 0.0)


def test_rows_are_numbers_of_the_models_each_once():
    assert ceiling.rows("1") == (1,)
    assert ceiling.rows(f"2, {len(ceiling.MODELS)}") == (2, len(ceiling.MODELS))
    for bad, said in (("0", "outside"), ("x", "not a whole number"), ("3,3", "twice"),
                      (str(len(ceiling.MODELS) + 1), "outside")):
        with pytest.raises(ceiling.argparse.ArgumentTypeError, match=said):
            ceiling.rows(bad)
    with pytest.raises(SystemExit) as stop:
        ceiling.main(["--rows", "0"])
    assert stop.value.code == 2


def test_files_are_the_monte_carlos_each_once(capsys):
    assert ceiling.files("realism_mc.toml") == ("realism_mc.toml",)
    assert ceiling.files(" realism_mc.toml, realism_mc_lugre_fresh.toml") == (
        "realism_mc.toml", "realism_mc_lugre_fresh.toml")
    for bad, said in (("paper.toml", "is not one of"), ("realism_mc.toml,realism_mc.toml",
                                                         "twice"), ("", "is not one of")):
        with pytest.raises(ceiling.argparse.ArgumentTypeError, match=said):
            ceiling.files(bad)
    with pytest.raises(SystemExit) as stop:
        ceiling.main(["--files", "/etc/passwd"])
    assert stop.value.code == 2
    assert "--files" in capsys.readouterr().err
    # every file it may name has rigid draws to approach
    assert all(ceiling.tables(name) for name in ceiling.FILE_CHOICES)


def test_the_identified_row_is_told_what_identify_finds(monkeypatch):
    import papwc.identify.excitation as excitation
    import papwc.identify.fit as fit

    class Identification:
        # the Stribeck curve chosen, the lag not (and a field the planner is not told)
        plant = {"m": 149.0, "f_c": 97.0, "c": 720.0, "v_s": 3e-3, "f_s": 131.0}

    logs = []
    monkeypatch.setattr(excitation, "design", lambda h, f_p_max, travel, duration: (
        h, f_p_max, travel, duration))
    monkeypatch.setattr(excitation, "apply_to_plant", lambda u, h, params: logs.append(
        (u, h, params)) or "log")
    monkeypatch.setattr(fit, "identify", lambda log, *args, **kwargs: Identification)
    told = ceiling.identified(LAG)
    assert told == {"m": 149.0, "f_c": 97.0, "c": 720.0, "v_s": 3e-3, "tau_u": 0.0}
    # the log: the design's defaults (papwc identify --design) applied to the table itself
    assert logs == [((0.01, 300.0, 0.05, 60.0), 0.01, LAG)]

    # the row's approach plans on those values (and no ripple), the table stepped as it is
    seen = []
    monkeypatch.setattr(ceiling, "identified",
                        lambda params, fields=None: seen.append(params) or told)
    row = next(m for m in ceiling.MODELS if m.identified)
    done = ceiling.approach({**LAG, "ripple": 0.05, "ripple_period": 2e-3}, row)
    assert seen and seen[0]["ripple"] == 0.05
    assert {k: done.model_params[k] for k in told} == told
    assert done.model_params["ripple"] == 0.0 and done.table.ripple is not None
    assert done.model.ripple is None
    # the next row takes the table's v_s instead of the one found
    same_but_v_s = ceiling.MODELS[ceiling.MODELS.index(row) + 1]
    done = ceiling.approach({**LAG, "v_s": 1e-3}, same_but_v_s)
    assert done.model_params["v_s"] == 1e-3
    assert {k: done.model_params[k] for k in told if k != "v_s"} == {
        k: v for k, v in told.items() if k != "v_s"}


def test_the_identified_row_is_not_run_on_lugre_tables(capsys):
    row = 1 + next(i for i, m in enumerate(ceiling.MODELS) if m.identified)
    ceiling.main(["--rows", str(row), "--files", "realism_mc_lugre.toml", "--tables", "1"])
    out = capsys.readouterr().out
    assert out.startswith("from rest") and "realism_mc_lugre.toml" not in out


def test_ctrl_c_gives_one_line_and_leaves_no_worker():
    import os
    import signal
    import subprocess
    import sys
    import time

    # Ctrl-C reaches the whole process group, the study's workers too: one of them busy
    # identifying the one table (minutes), the other waiting for work
    row = 1 + next(i for i, m in enumerate(ceiling.MODELS) if m.identified)
    proc = subprocess.Popen([sys.executable, "-m", "papwc_studies.ceiling", "--rows", str(row),
                             "--files", "realism_mc.toml", "--tables", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    time.sleep(4.0)
    os.killpg(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert err == "python -m papwc_studies.ceiling: interrupted\n"
    assert out.startswith("from rest")
    with pytest.raises(ProcessLookupError):  # the workers were terminated with the pool
        os.killpg(proc.pid, 0)
