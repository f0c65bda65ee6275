/*
 * test_main.c — one cmocka run over every group, so `make test` ends with a
 * single summary line.
 */
#include "test_util.h"

#include <stdio.h>
#include <string.h>

int main(void)
{
    const struct { const struct CMUnitTest *t; size_t n; } groups[] = {
        {world_tests, world_tests_count},
        {bounds_tests, bounds_tests_count},
        {view_tests, view_tests_count},
        {query_tests, query_tests_count},
        {occlusion_tests, occlusion_tests_count},
        {light_tests, light_tests_count},
        {render_tests, render_tests_count},
        {scene_render_tests, scene_render_tests_count},
        {post_tests, post_tests_count},
        {shadow_tests, shadow_tests_count},
        {brdf_tests, brdf_tests_count},
        {ssao_tests, ssao_tests_count},
        {alloc_tests, alloc_tests_count},
        {protocol_tests, protocol_tests_count},
        {bytes_tests, bytes_tests_count},
        {protocol_size_tests, protocol_size_tests_count},
        {protocol_doc_tests, protocol_doc_tests_count},
        {e2e_tests, e2e_tests_count},
        {exr_tests, exr_tests_count},
        {image_tests, image_tests_count},
        {h264_tests, h264_tests_count},
        {gl_tests, gl_tests_count},
        {overlay_tests, overlay_tests_count},
        {sublevel_tests, sublevel_tests_count},
        {destruct_tests, destruct_tests_count},
        {texture_tests, texture_tests_count},
        {texsample_tests, texsample_tests_count},
        {env_tests, env_tests_count},
        {mask_tests, mask_tests_count},
        {auth_tests, auth_tests_count},
        {http_tests, http_tests_count},
        {web_tests, web_tests_count},
        {persist_tests, persist_tests_count},
        {transform_tests, transform_tests_count},
        {material_tests, material_tests_count},
        {recover_tests, recover_tests_count},
        {cluster_rec_tests, cluster_rec_tests_count},
        {upgrade_tests, upgrade_tests_count},
        {pad_tests, pad_tests_count},
        {pad_io_tests, pad_io_tests_count},
        {commander_tests, commander_tests_count},
        {cmdr_wasm_tests, cmdr_wasm_tests_count},
        {metrics_tests, metrics_tests_count},
        {sched_tests, sched_tests_count},
        {bench_tests, bench_tests_count},
        {validate_tests, validate_tests_count},
        {cli_tests, cli_tests_count},
        {errmap_tests, errmap_tests_count},
        {import_tests, import_tests_count},
    };
    /* TEST_ROWS entries become one test per row (test_util.h) */
    size_t total = 0;
    for (size_t g = 0; g < sizeof groups / sizeof groups[0]; g++)
        total += test_rows_expand(groups[g].t, groups[g].n, NULL);
    struct CMUnitTest *all = calloc(total, sizeof *all);
    if (!all) return 1;
    for (size_t g = 0, at = 0; g < sizeof groups / sizeof groups[0]; g++)
        at += test_rows_expand(groups[g].t, groups[g].n, all + at);
    /* VANTAGE_TEST_ONLY=substring runs the tests whose name contains it */
    const char *only = getenv("VANTAGE_TEST_ONLY");
    size_t k = 0;
    for (size_t i = 0; i < total; i++) {
        if (!only || strstr(all[i].name, only)) all[k++] = all[i];
        else free((char *)all[i].name);
    }
    total = k;
    printf("vantage tests: seed 0x%llx, scale %g\n", (unsigned long long)test_seed(), test_scale());
    int failed = _cmocka_run_group_tests("vantage", all, total, NULL, NULL);
    for (size_t i = 0; i < total; i++) free((char *)all[i].name);
    free(all);
    return failed ? 1 : 0;
}
