/* client/commander_sdl.c — being written (issue 8) */
