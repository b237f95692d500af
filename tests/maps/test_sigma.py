"""The calibration of the maps' σ: likelihood, and the ±2σ band held within 90-98 % per group."""

import numpy as np
import pandas as pd
import pytest

from surrogate.maps.sigma import COVERAGE_BAND, SigmaCalibration, coverage_of


def light_and_heavy_tailed_errors(seed: int = 0):
    """Two groups of errors with one spread: one uniform (light tails: at its RMS σ, ±2σ holds
    them all), one Student-t with 3 degrees of freedom (heavy tails)."""
    rng = np.random.default_rng(seed)
    light = rng.uniform(-1.0, 1.0, 120) * np.sqrt(3.0) * 0.02
    heavy = rng.standard_t(3, 150) / np.sqrt(3.0) * 0.02
    errors = np.concatenate([light, heavy])
    groups = np.array(["light"] * len(light) + ["heavy"] * len(heavy))
    return errors, groups


def shares_inside(calibration, errors, groups):
    std = calibration.std(None, {})
    return {label: coverage_of(errors[groups == label], std[groups == label] if np.ndim(std)
                               else np.full((groups == label).sum(), std))
            for label in np.unique(groups)}


def test_likelihood_alone_lets_a_light_tailed_group_sit_wholly_inside():
    """The case the constraint exists for: without groups the fit is plain likelihood, whose
    σ (of the RMS) holds every light-tailed error within ±2σ."""
    errors, groups = light_and_heavy_tailed_errors()
    calibration = SigmaCalibration.fit(errors, None, {"d": np.zeros_like(errors)}, use_spread=False)
    assert shares_inside(calibration, errors, groups)["light"] == 1.0


def test_each_group_is_held_within_the_band():
    errors, groups = light_and_heavy_tailed_errors()
    # a distance that only the light group has lets σ differ between the groups
    distance = np.where(groups == "light", 1.0, 0.0)
    calibration = SigmaCalibration.fit(errors, None, {"d": distance}, use_spread=False,
                                  groups=groups)
    std = calibration.std(None, {"d": distance})
    for label in ("light", "heavy"):
        at = groups == label
        share = coverage_of(errors[at], std[at])
        assert COVERAGE_BAND[0] <= share <= COVERAGE_BAND[1], (label, share)


@pytest.mark.parametrize("seed", range(4))
def test_a_fit_already_inside_the_band_is_the_likelihood_fit(seed):
    """Gaussian errors whose ±2σ already holds 90-98 %: the constraint changes nothing."""
    rng = np.random.default_rng(seed)
    errors = rng.normal(0.0, 0.03, 400)
    groups = np.repeat(["a", "b"], 200)
    plain = SigmaCalibration.fit(errors, None, {}, use_spread=False)
    std = plain.std(None, {})
    if not all(COVERAGE_BAND[0] <= coverage_of(errors[groups == g], np.full(200, std))
               <= COVERAGE_BAND[1] for g in ("a", "b")):
        pytest.skip("this draw's likelihood fit is outside the band")
    grouped = SigmaCalibration.fit(errors, None, {}, use_spread=False, groups=groups)
    assert grouped == plain


def test_variance_known_to_be_in_the_errors_is_not_learned_again():
    """Errors whose variance is 1 % of the map's own plus a known 2 %: the fit finds the map's
    1 %, where one that does not know of the 2 % takes all of it (√5 % ≈ 2.2 %) as its own."""
    rng = np.random.default_rng(5)
    own_sigma, known = 0.01, np.full(4000, 0.02 ** 2)
    errors = rng.normal(0.0, np.sqrt(own_sigma ** 2 + known))
    told = SigmaCalibration.fit(errors, None, {}, use_spread=False, known=known)
    untold = SigmaCalibration.fit(errors, None, {}, use_spread=False)
    assert told.floor == pytest.approx(own_sigma, rel=0.15)
    assert untold.floor == pytest.approx(np.sqrt(own_sigma ** 2 + 0.02 ** 2), rel=0.05)


def test_a_distance_given_its_power_keeps_it_and_the_rest_share_the_fitted_one():
    """Errors that grow linearly along one distance and as its square along another: given the
    first's power, the fit keeps it and fits the other's; the powers go through a file."""
    rng = np.random.default_rng(3)
    linear, square = rng.uniform(0.0, 1.0, (2, 600))
    errors = rng.standard_normal(600) * np.hypot(0.05 * linear, 0.08 * square ** 2)
    distances = {"linear": linear, "square": square}
    calibration = SigmaCalibration.fit(errors, None, distances, use_spread=False,
                                       powers={"linear": 1.0, "absent": 3.0})
    assert calibration.powers == {"linear": 1.0}  # no power for a distance the errors lack
    assert calibration.power_of("linear") == 1.0
    assert calibration.power_of("square") == calibration.power
    assert 1.4 < calibration.power < 2.8
    again = SigmaCalibration.from_dict(calibration.to_dict())
    assert np.allclose(again.std(None, distances), calibration.std(None, distances))
    assert "powers" not in SigmaCalibration(slopes={"d": 1.0}).to_dict()  # files as before


def test_the_meshes_biases_are_in_a_left_out_openings_errors_only(cfd_samples):
    """σ_CFD²·(1 + share²) at a left-out opening (its own mesh's bias and its neighbours' as the
    map bridges them: 1 + ½ halfway in ln u), nothing where the training kept the mesh."""
    from surrogate.maps.cfd_error import FLOW_CFD_ERROR, FORCE_CFD_ERROR
    from surrogate.maps.crossval import SCHEMES, meshes_in_errors

    frame = cfd_samples.frame
    openings = np.unique(frame["u"].round(12))
    middle = frame.loc[np.isclose(frame["u"], openings[2]), "case"].iloc[0]
    errors = pd.DataFrame({"case": [middle, middle], "scheme": [SCHEMES[1], SCHEMES[0]]})
    flow, force = meshes_in_errors(errors, cfd_samples)
    low, high = np.log(openings[1]), np.log(openings[3])
    t = (np.log(openings[2]) - low) / (high - low)
    share_squared = (1 - t) ** 2 + t ** 2
    assert flow == pytest.approx([FLOW_CFD_ERROR ** 2 * (1 + share_squared), 0.0])
    assert force == pytest.approx([FORCE_CFD_ERROR ** 2 * (1 + share_squared), 0.0])


def test_each_distance_may_fit_a_power_of_its_own():
    """Errors linear along one distance and quadratic along another: with ``each_power`` the fit
    finds a power near 1 for the first and near 2 for the second, where one shared power lies
    between them."""
    rng = np.random.default_rng(4)
    linear, square = rng.uniform(0.0, 1.0, (2, 2000))
    errors = rng.standard_normal(2000) * np.hypot(0.05 * linear, 0.08 * square ** 2)
    distances = {"linear": linear, "square": square}
    own = SigmaCalibration.fit(errors, None, distances, use_spread=False, each_power=True)
    assert own.power_of("linear") == pytest.approx(1.0, abs=0.35)
    assert own.power_of("square") == pytest.approx(2.0, abs=0.5)
    shared = SigmaCalibration.fit(errors, None, distances, use_spread=False)
    assert own.power_of("linear") < shared.power < own.power_of("square")


def test_the_grid_force_errors_carry_the_meshes_their_folds_bridged(cfd_samples):
    """A grid fold that left the sample's opening out at its fluid level (its distance along the
    openings above 0: an opening left out, or a sweep) bridged the neighbours' meshes:
    σ_CFD²·(1 + share²); a fold that kept it (a temperature left out), nothing."""
    from surrogate.maps.cfd_error import FORCE_CFD_ERROR
    from surrogate.maps.grid import meshes_bridged_in_errors

    frame = cfd_samples.frame
    openings = np.unique(frame["u"].round(12))
    middle, smallest = (frame.loc[np.isclose(frame["u"], openings[i]), "case"].iloc[0]
                        for i in (2, 0))
    errors = pd.DataFrame({"case": [middle, smallest, middle],
                           "force_distance:opening": [0.2, 0.0, 0.0],
                           "force_distance:opening beyond": [0.0, 0.3, 0.0]})
    low, high = np.log(openings[1]), np.log(openings[3])
    t = (np.log(openings[2]) - low) / (high - low)
    bridged = FORCE_CFD_ERROR ** 2 * (1 + (1 - t) ** 2 + t ** 2)
    held = FORCE_CFD_ERROR ** 2 * 2  # beyond the end: the next opening's whole bias
    assert meshes_bridged_in_errors(errors, cfd_samples) == pytest.approx([bridged, held, 0.0])


def test_the_grids_flow_sigma_along_the_viscosity_has_the_interpolations_power(cfd_samples,
                                                                              valve):
    """The grid's folds err along ν only where a temperature was left out, every one at the same
    distance, so no power can be fitted to them: the calibration gives the viscosity the power of
    linear interpolation's error, 2, and σ from it at half a fold's distance is a quarter of
    the fold's (with the opening's fitted 2.7 it was 0.15 of it, and over 120 virtual valves the
    grid's ±2σ held 88 and 84 % of their q at 30 and 50 °C and in other oils)."""
    from surrogate.maps.grid import FLOW_POWERS, GridUncertainty, toward_seat

    uncertainty = GridUncertainty(cfd_samples, valve)
    errors = uncertainty.errors[~toward_seat(uncertainty.errors)]
    along = errors["flow_distance:viscosity"].to_numpy()
    assert len(np.unique(along[along > 0].round(9))) == 1
    flow = uncertainty.fitted_calibrations()["flow"]
    assert flow.power_of("viscosity") == FLOW_POWERS["viscosity"] == 2.0
    assert flow.power_of("opening") != 2.0  # the opening's power is still fitted
    fold = float(along[along > 0][0])
    own = {name: np.zeros(1) for name in flow.slopes}
    at = {distance: flow.std(None, {**own, "viscosity": np.array([distance])})[0] ** 2
          - flow.floor ** 2 for distance in (fold, fold / 2)}
    assert at[fold / 2] == pytest.approx(at[fold] / 16)


def test_sixteen_errors_in_a_group_leave_one_outside():
    """Of 16 errors, 15 inside is the only count in 90-98 %; 16 of 16 is refused."""
    rng = np.random.default_rng(3)
    errors = rng.uniform(-1.0, 1.0, 16) * 0.02
    calibration = SigmaCalibration.fit(errors, None, {}, use_spread=False,
                                  groups=np.zeros(16, int))
    std = np.full(16, calibration.floor)
    assert np.sum(np.abs(errors) > 2 * std) == 1


def test_a_group_too_small_for_the_band_is_left_to_the_likelihood():
    """Of 5 errors no count lies in 90-98 % (4 is 80 %, 5 is 100 %): such a group adds no
    constraint, and a fit whose other groups are inside the band is the likelihood's."""
    rng = np.random.default_rng(5)
    errors = np.concatenate([rng.normal(0.0, 0.03, 300), rng.uniform(-0.01, 0.01, 5)])
    groups = np.array(["many"] * 300 + ["few"] * 5)
    plain = SigmaCalibration.fit(errors, None, {}, use_spread=False)
    share = coverage_of(errors[:300], np.full(300, plain.floor))
    assert COVERAGE_BAND[0] <= share <= COVERAGE_BAND[1]
    assert SigmaCalibration.fit(errors, None, {}, use_spread=False, groups=groups) == plain


def test_the_opening_distance_is_zero_on_a_sampled_opening_and_grows_into_a_gap():
    """|ln u − ln(nearest sampled opening)|: what a learned map's σ grows with between openings
    (every opening is a mesh of its own, and the features alone do not carry that)."""
    from surrogate.maps.coverage import Coverage

    openings = np.array([0.1e-3, 0.2e-3, 0.4e-3, 1.6e-3])  # spacings ln 2, ln 2, ln 4
    coverage = Coverage(openings, *(np.ones(4),) * 4, np.ones(2), np.ones(2), np.array([0.0]))
    assert np.allclose(coverage.opening_distance(openings), 0.0)
    # as a share of half the closest spacing (ln 2 / 2)
    assert coverage.opening_distance(0.22e-3) == pytest.approx(np.log(1.1) / (np.log(2) / 2))
    # 1 from halfway to the closest neighbour on: what a left-out opening calibrates
    for far in (np.sqrt(0.1e-3 * 0.2e-3), 0.8e-3, 3.2e-3):
        assert coverage.opening_distance(far) == pytest.approx(1.0)
    # a left-out opening is at 1 in its fold: 0.2 mm left out of these
    fold = Coverage(openings[[0, 2, 3]], *(np.ones(3),) * 4, np.ones(2), np.ones(2),
                    np.array([0.0]))
    assert fold.opening_distance(0.2e-3) == pytest.approx(1.0)


def test_a_network_map_reads_the_opening_distance_of_its_own_samples_and_a_gp_its_posterior():
    from surrogate.fluid import FluidState
    from surrogate.maps.learned import load_learned_maps, trained_folder

    u = np.array([0.16e-3, 0.3e-3, 0.63e-3])
    fluid = FluidState(np.full(3, 32e-6), np.full(3, 870.0))
    for kind in ("nn", "gp"):
        flow_map, force_map = load_learned_maps(trained_folder(kind))
        for inputs in (flow_map.calibration_inputs(np.full(3, 1e-4), np.full(3, 20e5), u, fluid),
                       force_map.calibration_inputs(np.full(3, 150e5), np.full(3, 20e5), u,
                                                    fluid)):
            _, distances = inputs
            if kind == "gp":
                assert "opening" not in distances
                continue
            assert np.allclose(distances["opening"], force_map.coverage.opening_distance(u))
            assert distances["opening"][1] == 1.0 and distances["opening"][0] < 0.01


def test_the_shipped_grid_calibration_is_what_the_shipped_samples_give(tmp_path):
    """The grid's calibration and cross-validation summary are stored for the shipped samples
    and valve (surrogate/trained/grid/calibration.json) so that no command computes them again:
    they must be what the grid's own cross-validated errors give today, to the bit, and be used
    for exactly those samples and that valve."""
    from dataclasses import replace

    from surrogate import load_valve
    from surrogate.data import load_cfd_samples
    from surrogate.maps.grid import GridUncertainty
    from surrogate.maps.grid_sigma import (shipped_calibrations, shipped_summary,
                                                 write_calibrations)
    from surrogate.core.paths import SHIPPED_CFD_SAMPLES

    samples, valve = load_cfd_samples(SHIPPED_CFD_SAMPLES), load_valve(None)
    shipped = shipped_calibrations(samples, valve)
    assert shipped is not None, "no shipped grid calibration: python training/train.py --kinds grid"
    assert shipped == GridUncertainty(samples, valve).fitted_calibrations()
    assert GridUncertainty(samples, valve).calibrations == shipped
    accuracy = shipped_summary(samples, valve)
    assert accuracy is not None, "no shipped grid summary: python training/train.py --kinds grid"
    assert accuracy == GridUncertainty(samples, valve).computed_summary()
    assert GridUncertainty(samples, valve).summary() == accuracy
    fewer = samples.subset(np.arange(len(samples)) > 0)
    assert shipped_calibrations(fewer, valve) is None
    assert shipped_summary(fewer, valve) is None
    assert shipped_calibrations(samples, replace(valve, A_L=valve.A_L * 1.01)) is None
    assert shipped_summary(samples, replace(valve, A_L=valve.A_L * 1.01)) is None
    # a file written for other samples is not taken for these; one without a summary has none
    other = tmp_path / "calibration.json"
    write_calibrations(other, fewer, valve, shipped)
    assert shipped_calibrations(samples, valve, other) is None
    assert shipped_calibrations(fewer, valve, other) == shipped
    assert shipped_summary(fewer, valve, other) is None
    write_calibrations(other, fewer, valve, shipped, accuracy)
    assert shipped_summary(fewer, valve, other) == accuracy
    assert shipped_summary(samples, valve, other) is None


def test_the_grids_sigma_toward_the_seat_is_its_own_continuations_error():
    """Below its smallest opening the grid goes on from its two smallest openings; its σ there
    grows as fast as that continuation was measured to err (the smallest opening left out and
    continued to from the next two, :meth:`GridUncertainty.seat_slopes`), not at the slope of the
    folds that extrapolate elsewhere (above the largest opening, 0.20 → 0.63 mm, where C_d was
    held across a factor of three: that slope made ln C_d's σ 58 % at 0.015 mm)."""
    from surrogate import load_valve
    from surrogate.data import load_cfd_samples
    from surrogate.maps.cfd_error import SEAT_FLOW_ERROR, SEAT_FORCE_ERROR
    from surrogate.maps.grid import GridUncertainty, grid_maps_on
    from surrogate.maps.splits import leave_smallest_opening_out
    from surrogate.maps.crossval import errors_on
    from surrogate.core.paths import SHIPPED_CFD_SAMPLES

    samples, valve = load_cfd_samples(SHIPPED_CFD_SAMPLES), load_valve(None)
    flow_map, force_map = grid_maps_on(samples, valve)
    slopes = GridUncertainty(samples, valve).seat_slopes()
    # the continuation errs faster than the CFD's prior toward the seat, so the grid's own rules
    assert slopes["flow"] > SEAT_FLOW_ERROR and slopes["force"] > SEAT_FORCE_ERROR
    _, train, test, reach = leave_smallest_opening_out(samples.frame)
    errors = errors_on(*grid_maps_on(samples, valve, train), samples.frame[test], valve)
    assert np.sqrt(np.mean(errors["force_error"] ** 2)) == pytest.approx(slopes["force"] * reach)

    fluid = valve.oil.state(313.15)
    smallest = np.min(flow_map.coverage.openings)
    depth = np.array([0.5, 1.0, 1.2])  # ln(u₀/u); the shipped log reaches 1.2 (0.015 mm)
    u = smallest * np.exp(-depth)
    q, p_B = np.full(3, 2.0 / 60e3), np.full(3, 5e5)
    # σ = that continuation's error, with the CFD's own (a few per cent) in quadrature beside it
    flow_std = flow_map.log_discharge_std(q, p_B, u, fluid)
    assert np.all((flow_std >= slopes["flow"] * depth) & (flow_std < 1.1 * slopes["flow"] * depth))
    force_std = force_map.relative_force_std(p_B + 30e5, p_B, u, fluid)
    assert np.all((force_std >= slopes["force"] * depth)
                  & (force_std < 1.1 * slopes["force"] * depth))
