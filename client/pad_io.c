/* client/pad_io.c — being written (issue 8) */
