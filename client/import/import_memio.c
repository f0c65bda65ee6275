/*
 * import_memio.c — imp_level_import_mem (import.h): a level file held in
 * memory, read by assimp through an aiFileIO whose one file is the buffer,
 * in this process (a file that crashes assimp crashes the caller: the fuzz
 * target's entry). Nothing else opens: a glTF file's external buffers and
 * images and an OBJ's .mtl are not found. Cost: no copy of the buffer.
 */
#include "import_internal.h"

#include <assimp/cfileio.h>
#include <assimp/cimport.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The buffer, and one open file's position in it. */
typedef struct mem_file {
    const char *name;
    const uint8_t *buf;
    size_t len, pos;
} mem_file;

typedef struct mem_open_file {
    struct aiFile f;
    mem_file m;
} mem_open_file;

/* As assimp's own MemoryIOStream: whole items only, their count back. */
static size_t mem_read(struct aiFile *f, char *dst, size_t size, size_t count)
{
    mem_file *m = &((mem_open_file *)(void *)f->UserData)->m;
    if (!size) return 0;
    size_t n = (m->len - m->pos) / size;
    if (n > count) n = count;
    if (n) memcpy(dst, m->buf + m->pos, n * size);
    m->pos += n * size;
    return n;
}

static size_t mem_write(struct aiFile *f, const char *src, size_t size, size_t count)
{
    (void)f, (void)src, (void)size, (void)count;
    return 0;
}

static size_t mem_tell(struct aiFile *f)
{
    return ((mem_open_file *)(void *)f->UserData)->m.pos;
}

static size_t mem_size(struct aiFile *f)
{
    return ((mem_open_file *)(void *)f->UserData)->m.len;
}

/* As MemoryIOStream again: aiOrigin_END counts back from the end. */
static enum aiReturn mem_seek(struct aiFile *f, size_t off, enum aiOrigin origin)
{
    mem_file *m = &((mem_open_file *)(void *)f->UserData)->m;
    if (origin == aiOrigin_SET) {
        if (off > m->len) return aiReturn_FAILURE;
        m->pos = off;
    } else if (origin == aiOrigin_END) {
        if (off > m->len) return aiReturn_FAILURE;
        m->pos = m->len - off;
    } else {
        if (off > m->len - m->pos) return aiReturn_FAILURE;
        m->pos += off;
    }
    return aiReturn_SUCCESS;
}

static void mem_flush(struct aiFile *f)
{
    (void)f;
}

/* Only the one name opens, for reading: a glTF file's external buffers and
 * images and an OBJ's .mtl are not found. */
static struct aiFile *mem_open(struct aiFileIO *io, const char *name, const char *mode)
{
    const mem_file *m = (const mem_file *)(void *)io->UserData;
    if (strcmp(name, m->name) || mode[0] != 'r') return NULL;
    mem_open_file *o = calloc(1, sizeof *o);
    if (!o) return NULL;
    o->m = *m;
    o->f = (struct aiFile){.ReadProc = mem_read, .WriteProc = mem_write, .TellProc = mem_tell,
                           .FileSizeProc = mem_size, .SeekProc = mem_seek, .FlushProc = mem_flush,
                           .UserData = (aiUserData)(void *)o};
    return &o->f;
}

static void mem_close(struct aiFileIO *io, struct aiFile *f)
{
    (void)io;
    free(f->UserData);
}

int imp_level_import_mem(const void *buf, size_t len, const char *hint, imp_level *out, char *err, size_t errlen)
{
    memset(out, 0, sizeof *out);
    char name[32];
    if (strlen(hint) > 8 || !imp_known_format(hint)) {
        snprintf(err, errlen, "memory.%.8s: unsupported format (Vantage imports glTF 2.0 .gltf/.glb and OBJ .obj)",
                 hint);
        return -1;
    }
    snprintf(name, sizeof name, "memory.%s", hint);
    mem_file m = {.name = name, .buf = buf, .len = len};
    struct aiFileIO io = {.OpenProc = mem_open, .CloseProc = mem_close, .UserData = (aiUserData)(void *)&m};
    const struct aiScene *sc = aiImportFileEx(name, IMP_FLAGS, &io);
    if (!sc) {
        snprintf(err, errlen, "%s: cannot import: %s", name, aiGetErrorString());
        return -1;
    }
    const char *json = NULL;
    size_t jl = 0;
    if (strcmp(hint, "obj") && !imp_gltf_json(buf, len, &json, &jl)) json = NULL;
    return imp_level_from_scene(sc, name, NULL, json, jl, out, err, errlen);
}
