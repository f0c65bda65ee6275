/*
 * commander_sdl.c — the commander's window (commander.h): SDL2 shows the
 * streamed frames (one streaming texture, updated per frame; the daemon
 * drew the selection's outline and the marks' icons into them), the
 * overlay is drawn with SDL's renderer (reticle, mark rings) and SDL_ttf
 * (status lines, DejaVu Sans Mono from fonts-dejavu-core; without the
 * font the lines go to the window title instead).
 *
 * Cost: a 1280x720 RGB upload and a present per frame (~1 ms with a GPU,
 * 2-4 ms on Xvfb's software path); text is re-rendered only when it
 * changes.
 */
#include "commander.h"

#include <SDL.h>
#include <SDL_ttf.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "vt_image.h"

#define FONT_PATH "/usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf"

struct cmdr_display {
    SDL_Window *win;
    SDL_Renderer *ren;
    SDL_Texture *tex;
    uint32_t tw, th;         /* the texture's size */
    bool have_frame;
    TTF_Font *font;
    SDL_Texture *text[CMDR_OVERLAY_LINES];
    char text_src[CMDR_OVERLAY_LINES][192];
    int text_w[CMDR_OVERLAY_LINES], text_h[CMDR_OVERLAY_LINES];
    char title[256];
    cmdr_keys keys;           /* the held state between calls */
};

cmdr_display *cmdr_display_open(uint32_t w, uint32_t h, const char *title, char *err, size_t errlen)
{
    if (SDL_Init(SDL_INIT_VIDEO)) {
        snprintf(err, errlen, "cannot open a window: SDL has no video driver: %s (without a display, --headless DIR "
                 "writes the frames to a folder)", SDL_GetError());
        return NULL;
    }
    /* With no X11 or Wayland display SDL falls back to its offscreen (or
       dummy) driver: the window opens, draws, and nobody sees it. Refuse
       that unless asked for by name (SDL_VIDEODRIVER=offscreen). */
    const char *drv = SDL_GetCurrentVideoDriver(), *asked = SDL_getenv("SDL_VIDEODRIVER");
    if (drv && (!strcmp(drv, "offscreen") || !strcmp(drv, "dummy")) && !(asked && strstr(asked, drv))) {
        const char *disp = SDL_getenv("DISPLAY"), *wl = SDL_getenv("WAYLAND_DISPLAY");
        snprintf(err, errlen,
                 "cannot open a window: no display (DISPLAY %s%s%s, WAYLAND_DISPLAY %s%s%s; SDL found only its %s "
                 "driver, which shows nothing). Use --headless DIR to write the frames to a folder, or run under a "
                 "display (Xvfb :9 & DISPLAY=:9 ...)",
                 disp && *disp ? "is " : "unset", disp && *disp ? disp : "", disp && *disp ? " and unusable" : "",
                 wl && *wl ? "is " : "unset", wl && *wl ? wl : "", wl && *wl ? " and unusable" : "", drv);
        SDL_Quit();
        return NULL;
    }
    cmdr_display *d = calloc(1, sizeof *d);
    if (!d) {
        snprintf(err, errlen, "out of memory");
        SDL_Quit();
        return NULL;
    }
    d->win = SDL_CreateWindow(title, SDL_WINDOWPOS_CENTERED, SDL_WINDOWPOS_CENTERED, (int)w, (int)h, 0);
    /* no vsync: waiting for the display's refresh would add up to a refresh to every frame's latency */
    if (d->win) d->ren = SDL_CreateRenderer(d->win, -1, 0);
    if (!d->ren) {
        snprintf(err, errlen, "cannot open a window: %s (without a display, --headless DIR writes the frames to a "
                 "folder)", SDL_GetError());
        cmdr_display_close(d);
        return NULL;
    }
    SDL_SetRenderDrawBlendMode(d->ren, SDL_BLENDMODE_BLEND);
    snprintf(d->title, sizeof d->title, "%s", title);
    if (TTF_Init() == 0) {
        d->font = TTF_OpenFont(FONT_PATH, 15);
        if (!d->font) fprintf(stderr, "vantage commander: %s: %s; status goes to the title\n", FONT_PATH, TTF_GetError());
    }
    return d;
}

void cmdr_display_close(cmdr_display *d)
{
    if (!d) return;
    for (int i = 0; i < CMDR_OVERLAY_LINES; i++)
        if (d->text[i]) SDL_DestroyTexture(d->text[i]);
    if (d->font) TTF_CloseFont(d->font);
    if (TTF_WasInit()) TTF_Quit();
    if (d->tex) SDL_DestroyTexture(d->tex);
    if (d->ren) SDL_DestroyRenderer(d->ren);
    if (d->win) SDL_DestroyWindow(d->win);
    free(d);
    SDL_Quit();
}

int cmdr_display_frame(cmdr_display *d, const uint8_t *rgb8, uint32_t w, uint32_t h)
{
    if (!d->tex || d->tw != w || d->th != h) {
        if (d->tex) SDL_DestroyTexture(d->tex);
        d->tex = SDL_CreateTexture(d->ren, SDL_PIXELFORMAT_RGB24, SDL_TEXTUREACCESS_STREAMING, (int)w, (int)h);
        if (!d->tex) return -1;
        d->tw = w;
        d->th = h;
    }
    if (SDL_UpdateTexture(d->tex, NULL, rgb8, (int)(3 * w))) return -1;
    d->have_frame = true;
    return 0;
}

/* Frame pixels -> window pixels (the frame is stretched over the window). */
static void to_win(const cmdr_display *d, double x, double y, int *wx, int *wy)
{
    int ww, wh;
    SDL_GetRendererOutputSize(d->ren, &ww, &wh);
    double sx = d->tw ? (double)ww / d->tw : 1, sy = d->th ? (double)wh / d->th : 1;
    *wx = (int)lround(x * sx);
    *wy = (int)lround(y * sy);
}

static void draw_text(cmdr_display *d, int i, const char *s, int y)
{
    if (strcmp(d->text_src[i], s) || (!d->text[i] && *s)) {
        snprintf(d->text_src[i], sizeof d->text_src[i], "%s", s);
        if (d->text[i]) SDL_DestroyTexture(d->text[i]);
        d->text[i] = NULL;
        if (*s) {
            SDL_Surface *srf = TTF_RenderUTF8_Blended(d->font, s, (SDL_Color){255, 255, 255, 255});
            if (srf) {
                d->text[i] = SDL_CreateTextureFromSurface(d->ren, srf);
                d->text_w[i] = srf->w;
                d->text_h[i] = srf->h;
                SDL_FreeSurface(srf);
            }
        }
    }
    if (!d->text[i]) return;
    SDL_SetRenderDrawColor(d->ren, 0, 0, 0, 150);
    SDL_RenderFillRect(d->ren, &(SDL_Rect){6, y - 1, d->text_w[i] + 8, d->text_h[i] + 2});
    SDL_RenderCopy(d->ren, d->text[i], NULL, &(SDL_Rect){10, y, d->text_w[i], d->text_h[i]});
}

static void draw_all(cmdr_display *d, const cmdr_overlay *ov)
{
    SDL_SetRenderDrawColor(d->ren, 20, 20, 24, 255);
    SDL_RenderClear(d->ren);
    if (d->have_frame) SDL_RenderCopy(d->ren, d->tex, NULL, NULL);
    int ww, wh;
    SDL_GetRendererOutputSize(d->ren, &ww, &wh);
    /* the reticle: a gapped cross at the centre */
    int cx = ww / 2, cy = wh / 2;
    SDL_SetRenderDrawColor(d->ren, 255, 255, 255, 230);
    for (int s = -1; s <= 1; s += 2) {
        SDL_RenderDrawLine(d->ren, cx + s * 6, cy, cx + s * 18, cy);
        SDL_RenderDrawLine(d->ren, cx, cy + s * 6, cx, cy + s * 18);
    }
    SDL_RenderDrawPoint(d->ren, cx, cy);
    /* the selection's outline and the marks' icons are in the frame (the
       daemon draws them: vt_overlay.h); marks get a ring here too, a
       diamond (ping) or a square (select) around the daemon's icon, in
       this client's colour or the others', fading out */
    for (uint32_t i = 0; ov && i < ov->nmarks; i++) {
        int x, y;
        to_win(d, ov->mark[i].x, ov->mark[i].y, &x, &y);
        Uint8 a = (Uint8)(255 * ov->mark[i].alpha);
        if (ov->mark[i].own) SDL_SetRenderDrawColor(d->ren, 80, 220, 255, a);
        else SDL_SetRenderDrawColor(d->ren, 255, 90, 90, a);
        for (int r = 9; r <= 11; r++) {
            if (ov->mark[i].kind == 0) {
                SDL_Point p[5] = {{x, y - r}, {x + r, y}, {x, y + r}, {x - r, y}, {x, y - r}};
                SDL_RenderDrawLines(d->ren, p, 5);
            } else {
                SDL_RenderDrawRect(d->ren, &(SDL_Rect){x - r, y - r, 2 * r + 1, 2 * r + 1});
            }
        }
    }
    if (ov) {
        if (d->font) {
            for (int i = 0; i < CMDR_OVERLAY_LINES; i++) draw_text(d, i, ov->text[i], 8 + i * 20);
        } else if (strcmp(d->text_src[0], ov->text[0])) {
            snprintf(d->text_src[0], sizeof d->text_src[0], "%s", ov->text[0]);
            SDL_SetWindowTitle(d->win, ov->text[0]);
        }
    }
}

void cmdr_display_present(cmdr_display *d, const cmdr_overlay *ov)
{
    draw_all(d, ov);
    SDL_RenderPresent(d->ren);
}

/* SDL's scancodes are the USB HID usages cmdr_key_table lists. */
_Static_assert(SDL_SCANCODE_A == 4 && SDL_SCANCODE_W == 26 && SDL_SCANCODE_RETURN == 40 &&
                   SDL_SCANCODE_LEFTBRACKET == 47 && SDL_SCANCODE_HOME == 74 && SDL_SCANCODE_UP == 82,
               "SDL scancodes are USB HID usages");

/* Held keys -> a pad state (pad_map.c's table, which the browser's page reads too). */
static void keys_state(cmdr_keys *k)
{
    const Uint8 *ks = SDL_GetKeyboardState(NULL);
    bool down[CMDR_KEYS];
    for (int i = 0; i < CMDR_KEYS; i++) down[i] = ks[cmdr_key_table[i].usage] != 0;
    pad_state s;
    bool any = cmdr_keys_pad(down, &s);
    if (any != k->any || memcmp(&s, &k->state, sizeof s)) k->changed = true;
    k->any = any;
    k->state = s;
}

void cmdr_display_events(cmdr_display *d, cmdr_keys *k)
{
    *k = d->keys;
    k->changed = false;
    k->wheel = 0;
    k->click = false;
    SDL_Event ev;
    while (SDL_PollEvent(&ev)) {
        switch (ev.type) {
        case SDL_QUIT: k->quit = true; break;
        case SDL_KEYDOWN:
            if (ev.key.keysym.sym == SDLK_ESCAPE ||
                (ev.key.keysym.sym == SDLK_q && (ev.key.keysym.mod & KMOD_CTRL)))
                k->quit = true;
            break;
        case SDL_MOUSEWHEEL:
            k->wheel += ev.wheel.direction == SDL_MOUSEWHEEL_FLIPPED ? -ev.wheel.y : ev.wheel.y;
            k->changed = true;
            break;
        case SDL_MOUSEBUTTONDOWN:
            if (ev.button.button == SDL_BUTTON_LEFT) {
                int ww, wh;
                SDL_GetWindowSize(d->win, &ww, &wh);
                k->click = true;
                k->click_x = ww ? (double)ev.button.x * d->tw / ww : 0;
                k->click_y = wh ? (double)ev.button.y * d->th / wh : 0;
                k->changed = true;
            }
            break;
        default: break;
        }
    }
    keys_state(k);
    d->keys = *k;
}

int cmdr_display_screenshot(cmdr_display *d, const cmdr_overlay *ov, const char *path, char *err, size_t errlen)
{
    draw_all(d, ov); /* what was presented: the back buffer is undefined after a present */
    int w, h;
    SDL_GetRendererOutputSize(d->ren, &w, &h);
    uint8_t *px = malloc((size_t)w * h * 4);
    if (!px) {
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    if (SDL_RenderReadPixels(d->ren, NULL, SDL_PIXELFORMAT_ABGR8888, px, 4 * w)) {
        snprintf(err, errlen, "reading the window: %s", SDL_GetError());
        free(px);
        return -1;
    }
    int rc = vt_png_write(path, (uint32_t)w, (uint32_t)h, px, 4 * (size_t)w, false, 6, err, errlen);
    free(px);
    return rc ? -1 : 0;
}
