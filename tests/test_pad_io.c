/* tests/test_pad_io.c — being written (issue 8) */
#include "test_util.h"

static void test_pad_io_placeholder(void **state)
{
    (void)state;
    skip();
}

const struct CMUnitTest pad_io_tests[] = {
    cmocka_unit_test(test_pad_io_placeholder),
};
const size_t pad_io_tests_count = sizeof pad_io_tests / sizeof pad_io_tests[0];
