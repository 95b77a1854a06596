"""Shared test fixtures (the seed's data, skipped when ../shared is absent) and the suite's markers and tiers.

The tiers: ``python -m pytest tests`` runs the default tier (every test not marked ``slow``);
``python -m pytest tests -m slow`` the slow tier; ``-m ""`` both. CI runs both (``.ci/run``). The
markers that say what a test needs (``cuda``, ``browser``, ``notebook``, ``cluster``) are given here
from :data:`NEEDS`, so ``-m "not browser"`` and the like select by need; the slow tier is
:data:`SLOW`, each entry with the measurement that put it there.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("WARP_SPT_SHARED", REPO.parent / "shared"))   # a worktree may point elsewhere
SEED_DEMO = SHARED / "seed" / "demo"

os.environ.setdefault("WARP_SPT_QUIET", "1")

# What a test needs beyond the base install, by file (or "file::test" prefix): its markers.
NEEDS = {
    "tests/gpu/": ("cuda",),
    "tests/viewer/test_viewer_browser.py": ("browser",),
    "tests/house/test_notebooks.py": ("notebook",),
    "tests/viewer/test_viewer_widget.py": ("notebook",),
    "tests/library/test_cluster.py": ("cluster",),
    "tests/house/test_readme.py::test_every_python_block_runs_as_a_script_from_an_empty_folder[cluster]": ("cluster",),
}
# The slow tier: node-id prefixes (a file, or "file::test"), each with why. Cold figures are from a
# run on 2 cores with an empty Warp kernel cache. A test stays in the default tier unless it alone
# costs minutes, or it is among a file's heaviest checks and the default tier needs the room for its
# 10 minutes (the file's other tests stay: each area keeps checks in the default tier).
# Figures: seconds of each test in one run of the whole suite on 2 workers at load 4-6 (2026-12-01).
SLOW: dict[str, str] = {
    "tests/gpu/test_cuda_compile.py": "NVRTC compiles the representative set for a GPU this machine lacks: "
                                      "194 s of 2 threads with Warp's cache cold (one fast kernel "
                                      "optimised, the rest in debug mode)",
    "tests/diff/test_volumes_gradients.py::test_interior_medium_gradients": "522 s: 8 seeds x 7 FD pairs at 256 spp "
                                                                           "(9 s after the fog test, whose kernels it shares)",
    "tests/diff/test_volumes_gradients.py::test_grid_gradients": "309 s: the same for a density grid",
    "tests/diff/test_volumes_gradients.py::test_furnace_gradients_vanish": "229 s",
    "tests/diff/test_volumes_gradients.py::test_fog_gradients": "202 s",
    "tests/house/test_notebooks.py": "176 s: every notebook executed in a Jupyter kernel",
    "tests/integrators/test_light_transport.py::test_light_pdfs_integrate_to_one_and_match_sampling":
        "217 s for the sky case alone: a dense sphere of directions per light kind",
    "tests/integrators/test_light_transport.py::test_nee_matches_polygon_irradiance": "159 s",
    "tests/integrators/test_light_transport.py::test_lobe_pdf_integrates_to_its_probability_and_matches_sampling":
        "90 s for the rough-metal case",
    "tests/emitters/test_emissive_texels.py::test_sampled_density_is_what_mis_evaluates": "128 s",
    "tests/emitters/test_emissive_texels.py::test_the_lamps_texture_gradient_holds_the_cells_fixed":
        "139 s: tape and path replay against finite differences",
    "tests/diff/test_pbr_gradients.py::test_pbr_gradients_are_the_derivative_of_the_expected_image":
        "96 s: the pbr kind's adjoint kernels, tape and replay",
    "tests/diff/test_param_gradients.py::test_colour_gradients_match_finite_differences": "67 s",
    "tests/integrators/test_light_transport.py::test_nee_with_a_light_too_unlikely_to_share_its_pick_number":
        "61 s at 2**15 samples a pixel; at 2**14 41 -> 20 s warm (one run on 2 busy cores), the NEE kernels' "
        "compile on top when cold",
    "tests/integrators/test_ears.py::test_ears_converges_to_the_same_image_as_nee": "56 s",
    "tests/hardening/test_fuzz_api.py::test_fuzzed_render_arguments_render_or_name_the_argument":
        "45 s: a kernel variant per drawn feature set",
    "tests/house/test_house_engine.py::test_every_kernel_kind_is_built_once_in_the_one_cache": "44 s",
    "tests/media/test_volumes_mitsuba.py::test_volpath_matches_mitsuba": "38 s",
    "tests/integrators/test_vertex_hooks.py::test_hooks_that_change_nothing_give_nee_bit_for_bit": "37 s",
    "tests/emitters/test_envmap.py::test_strength_gradient_is_the_image_over_the_strength": "36 s",
    "tests/media/test_volumes.py::test_emitting_box_equilibrium": "31 s",
    "tests/integrators/test_guiding.py::test_guided_converges_to_the_same_image_as_nee": "30 s",
    "tests/bsdfs/test_materials.py::test_cutouts_are_holes_for_camera_rays_and_shadow_rays": "30 s",
    # Figures: seconds in the default tier of a cold .ci/run of 6be2909 (2 cores, 715 s in all), moved
    # here to hold that tier to its 10 minutes; each is its file's heaviest check, the file's others stay
    "tests/emitters/test_light_tree.py::test_tree_sampling_density_is_what_mis_evaluates":
        "49 s: the light-pdf test kernels over every feature (the slow tier's pdf tests share them)",
    "tests/emitters/test_envmap_texels.py::test_texel_gradient_is_the_finite_difference_sample_for_sample": "33 s",
    "tests/diff/test_camera_sky_proctex_gradients.py::test_camera_gradients_match_finite_differences": "31 s",
    "tests/rendering/test_stability.py::test_cornell_box_gives_the_same_image_at_every_scale_and_offset": "29 s",
    "tests/diff/test_pbr_gradients.py::test_pbr_ior_gradient_through_the_tape": "29 s: the pbr kind's tape",
    "tests/diff/test_prb.py::test_path_replay_equals_the_tape": "27 s",
    "tests/emitters/test_punctual.py::test_light_gradients_match_finite_differences": "27 s",
    "tests/viewer/test_viewer_lighting.py::test_light_and_fog_messages_change_the_image": "27 s",
    "tests/bsdfs/test_microfacet.py::test_sampled_directions_follow_the_pdf": "19 s",
    "tests/viewer/test_viewer_lighting.py::test_the_copied_command_renders_the_lit_and_foggy_view": "17 s",
    "tests/house/test_readme.py::test_the_readme_gradients_example_runs_as_written": "17 s",
    "tests/emitters/test_envmap.py::test_rotation_gradient_matches_finite_differences": "15 s",
    "tests/rendering/test_interrupt.py::test_the_signal_tests_pass_in_a_run_started_with_sigint_ignored":
        "15 s: the signal tests again, in a process started with SIGINT ignored",
    "tests/emitters/test_punctual.py::test_only_delta_lights_render": "15 s",
    "tests/first_view/test_models.py::test_a_cold_kernel_cache_is_announced_once":
        "14 s: compiles into an empty kernel cache of its own",
    "tests/cli/test_light_flags_every_front_end.py::test_the_cluster_api_ships_a_scenes_lights_fog_and_environment":
        "14 s: a Dask cluster",
    "tests/cli/test_cli_progressive.py::test_a_time_budget_leaves_room_for_the_denoiser": "14 s",
    "tests/hardening/test_fuzz_api.py::test_fuzzed_integrator_options_that_are_taken_render_finite_in_bounded_time":
        "14 s",
    # Figures: seconds in the default tier of a cold .ci/run of 3efbddc (2 cores, 629 s in all: the
    # checks above had left, but the kernels they compiled were compiled by the tests sharing them)
    "tests/diff/test_prb.py::test_depth_beyond_the_tape_matches_finite_differences": "23 s",
    "tests/cli/test_light_flags_every_front_end.py::test_frame_alone_in_a_sequence_and_on_workers_is_the_same_image":
        "22 s: worker processes",
    "tests/viewer/test_viewer_browser.py::test_the_lights_and_fog_controls": "20 s: Chromium",
    "tests/bsdfs/test_materials_mitsuba.py::test_pbr_matches_mitsuba": "18 s",
    "tests/emitters/test_envmap_texels.py::test_texel_gradient_with_a_detached_distribution_is_unbiased": "15 s",
    "tests/first_view/test_users_first_files.py::test_no_studio_and_a_scene_with_its_own_light": "15 s",
    "tests/bsdfs/test_microfacet.py::test_pdf_integrates_to_the_probability_of_a_sample": "14 s",
    "tests/rendering/test_stability.py::test_million_samples_accumulate_without_drift": "13 s",
    "tests/rendering/test_instanced_render.py::test_instances_render_as_the_flattened_scene": "13 s",
    "tests/hardening/test_bounds_memory_and_signals.py::"
    "test_the_room_at_the_largest_accepted_size_renders_as_the_room_at_unit_size": "13 s",
    "tests/emitters/test_several_infinite_lights.py::"
    "test_each_kind_declares_its_part_and_one_infinite_light_is_as_before": "13 s",
    "tests/cli/test_light_flags_every_front_end.py::test_the_animation_api_takes_lights_and_fog_as_a_single_render_does":
        "13 s",
    "tests/accel/test_instances.py::test_instanced_hits_equal_the_flattened_scene": "12 s",
    "tests/rendering/test_aux_buffers.py::test_albedo_is_the_colour_of_the_first_non_specular_surface": "11 s",
    "tests/diff/test_param_gradients.py::test_texel_gradients_match_finite_differences": "11 s",
    "tests/rendering/test_interrupt.py::test_real_processes_interrupted_at_random_moments": "11 s: processes",
    "tests/hardening/test_bad_text_paths_and_flags.py::test_ctrl_c_to_the_process_group_with_local_workers_is_one_line":
        "11 s: worker processes",
    "tests/diff/test_geometry_gradients.py": "about 130 s warm (1-39 s a test: 4 gradient seeds and 16-32 renders "
                                             "of 512-8192 spp per check; the shadow's 39 s) after 40-60 s "
                                             "of compiling its four kernels",
    "tests/diff/test_pose_estimation.py": "the example's --quick run in a process of its own: 25 s warm, "
                                          "its scene's three kernels compiled first",
    "tests/diff/test_shape_from_views.py": "the example's --quick run in a process of its own: 37-58 s on 2 "
                                           "loaded cores (30 iterations of 6 views; 8 views took 101 s cold)",
    # Figures: seconds in the default tier of a cold run of both tiers on 2 cores at load (2026-12-03),
    # moved here when CI's default tier on 90d52fa took 620 s; each file's other tests stay
    "tests/diff/test_replay_pathwise.py::test_the_pathwise_replay_gives_the_tapes_geometry_and_camera_gradients[nee]":
        "34 s: the pathwise replay kernel under nee (its seed case stays)",
    "tests/media/test_volume_flag.py::test_volume_places_the_grid_in_its_own_bounds_as_a_hand_built_box_would": "26 s",
    "tests/media/test_volumes.py::test_a_fog_at_the_largest_accepted_g_drops_no_sample": "20 s",
    "tests/media/test_volumes.py::test_majorant_invariance": "17 s",
    # The readers' long fuzzing runs (1,500 cases each; their short runs of 25 stay): seconds on 2
    # cores, warm (2026-12-02), 38 s together
    "tests/hardening/test_reader_fuzz.py::test_gltf_files_with_extreme_values_load_or_name_file_and_pointer_long":
        "12 s",
    "tests/hardening/test_reader_fuzz.py::test_mutated_ply_scenes_load_or_name_the_file_long": "11 s",
    "tests/hardening/test_reader_fuzz.py::test_mutated_environment_images_read_or_name_the_file_long":
        "5 s, with the others of its run",
    "tests/hardening/test_reader_fuzz.py::test_mutated_light_files_load_or_name_file_and_line_long":
        "5 s, with the others of its run",
    "tests/hardening/test_reader_fuzz.py::test_mutated_nanovdb_grids_load_or_name_the_file_long":
        "5 s, with the others of its run",
}
# Beside SLOW, the tests that check every integrator x sampler pair run a covering set by default and
# the other pairs in the slow tier (tests/support/combos.py): 512 s of the same run for all 15 pairs.


def pytest_configure(config):
    """A run started in the background (``nohup pytest &``, a script's ``&``) inherits an ignored
    SIGINT, and so would every process it starts: the tests of Ctrl-C need the disposition a terminal
    gives. A Python handler here also means SIG_DFL in every child the tests start (exec resets
    handled signals, not ignored ones)."""
    import signal

    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_collection_modifyitems(config, items):
    """Markers from NEEDS and SLOW, and ``cluster`` for every test that starts a Dask client."""
    import inspect

    for item in items:
        node = item.nodeid
        for prefix, marks in NEEDS.items():
            if node.startswith(prefix):
                for mark in marks:
                    item.add_marker(mark)
        if any(node.startswith(prefix) for prefix in SLOW):
            item.add_marker("slow")
        function = getattr(item, "function", None)
        if function is not None and "cluster" not in item.keywords:
            try:
                source = inspect.getsource(function)
            except (OSError, TypeError):
                source = ""
            if "dask.distributed" in source or "client" in getattr(item, "fixturenames", ()):
                item.add_marker("cluster")


@pytest.fixture(scope="session")
def seed_demo() -> Path:
    """The seed's demo folder; the test is skipped where ../shared is not beside the repo."""
    if not (SEED_DEMO / "cornell_export.obj").is_file():
        pytest.skip("../shared/seed/demo is absent (a user's clone has no shared/)")
    return SEED_DEMO


@pytest.fixture(scope="session")
def scene_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("scenes")
