/* client/pad.c — being written (issue 8) */
