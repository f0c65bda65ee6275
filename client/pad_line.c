/* client/pad_line.c — being written (issue 8) */
