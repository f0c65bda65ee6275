/* client/pad_io_real.c — being written (issue 8) */
