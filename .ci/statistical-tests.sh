#!/usr/bin/env bash
# The statistical tests (docs/testing.md, "Statistical tests and their seed"): every test whose
# verdict depends on LUMIS_TEST_SEED, i.e. every test that draws from `chi2::test_sampler` or a
# default `Chi2Test`. Run it under the seeds you want:
#
#   LUMIS_TEST_SEED=3 .ci/statistical-tests.sh --locked
#   for seed in $(seq 0 9); do LUMIS_TEST_SEED=$seed .ci/statistical-tests.sh --locked -q; done
#
# Arguments go to every `cargo test`. Each run keeps `--workspace` so that the features, and
# hence the binaries, are those of `cargo test --workspace`: after the suite, nothing rebuilds.
# Every group is run even when one fails; the failing groups are named at the end (exit 1).
set -uo pipefail
cd "$(dirname "$0")/.."
# One group per line: cargo's target selection, then `--`, then test-name filters (none: the
# whole binary, all of whose tests take the seed). lumis-core's unit tests (the only library
# with any) run under `--tests`, which selects the libraries whose `[lib] test` is on; `--lib`
# would build every library as a test, those that have none too.
groups=(
    "--tests -- chi2:: testing:: filter::tests:: passes::tests::planned_weights error_estimate::tests::the_relative_error error_estimate::tests::the_conservative_nu budgets::tests::"
    "--test sampling"
    "--test bsdfs"
    "--test emitters -- emitters:: envmap_bilinear:: envmap::compensated"
    "--test integration -- robustness::plugin_library surfaces:: study_analysis::summary::nominal"
    "--test mis_methods -- convergence::example_methods_converge_to_balance"
    "--test integration -- integrators::same_mean_ learning:: integrators::every_integrator_gives_the_closed_form_at_one_point path::a_furnace_gives path::every_weighting_gives path::optimal_mis_gives path::the_deeper_mixture_gives path::sampling_weights_choose path::the_mixture_chooses path::the_mixture_samples passes::a_stop_after_seeing"
)
failed=()
for group in "${groups[@]}"; do
    read -r -a selection <<<"$group"
    # Options given to the script go before the group's `--`.
    split=${#selection[@]}
    for i in "${!selection[@]}"; do [ "${selection[$i]}" = "--" ] && split=$i && break; done
    if ! cargo test --workspace "$@" "${selection[@]:0:$split}" "${selection[@]:$split}"; then
        failed+=("$group")
    fi
done
seed=${LUMIS_TEST_SEED:-0}
if [ ${#failed[@]} -gt 0 ]; then
    echo "seed $seed: FAILED: $(printf '[%s] ' "${failed[@]}")"
    exit 1
fi
echo "seed $seed: every statistical test passed"
