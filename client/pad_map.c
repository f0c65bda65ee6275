/* client/pad_map.c — being written (issue 8) */
