/* client/pad_parse.c — being written (issue 8) */
