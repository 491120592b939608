/* Check a self-contained FMU's bundled files against the list its build wrote, before any of
 * them is opened: a truncated libpython would crash the host (SIGBUS) the moment it is mapped,
 * a damaged stdlib.zip would end in Python's path-configuration dump. Included by the loaders
 * (loader.c); needs libc only.
 *
 *   int bundle_check(const char *root, const char *list, const char *only, char *why,
 *                    size_t why_size)
 *
 * root: the unpacked FMU's folder; list: the list's path inside it (models/embed.py writes
 * resources/python/MANIFEST); only: NULL for every file, else the one path to check (a host's
 * own Python needs only pythonfmu's library: the bundled Python is not opened). Each line of the list is "<size> <sha-256 hex> <path>", the path
 * relative to root. Returns 0 when every file has its size and hash, else -1 with one line in
 * why naming the first file that differs and how. */
#ifndef BUNDLE_CHECK_H
#define BUNDLE_CHECK_H

#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* SHA-256 (FIPS 180-4) */
typedef struct {
    uint32_t state[8];
    uint64_t length;
    unsigned char block[64];
    size_t used;
} bundle_sha256;

static const uint32_t bundle_k[64] = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};

#define BUNDLE_ROR(x, n) (((x) >> (n)) | ((x) << (32 - (n))))

static void bundle_sha256_block(bundle_sha256 *s, const unsigned char *p)
{
    uint32_t w[64];
    for (int i = 0; i < 16; i++)
        w[i] = (uint32_t)p[4 * i] << 24 | (uint32_t)p[4 * i + 1] << 16
               | (uint32_t)p[4 * i + 2] << 8 | p[4 * i + 3];
    for (int i = 16; i < 64; i++) {
        uint32_t s0 = BUNDLE_ROR(w[i - 15], 7) ^ BUNDLE_ROR(w[i - 15], 18) ^ (w[i - 15] >> 3);
        uint32_t s1 = BUNDLE_ROR(w[i - 2], 17) ^ BUNDLE_ROR(w[i - 2], 19) ^ (w[i - 2] >> 10);
        w[i] = w[i - 16] + s0 + w[i - 7] + s1;
    }
    uint32_t a = s->state[0], b = s->state[1], c = s->state[2], d = s->state[3];
    uint32_t e = s->state[4], f = s->state[5], g = s->state[6], h = s->state[7];
    for (int i = 0; i < 64; i++) {
        uint32_t t1 = h + (BUNDLE_ROR(e, 6) ^ BUNDLE_ROR(e, 11) ^ BUNDLE_ROR(e, 25))
                      + ((e & f) ^ (~e & g)) + bundle_k[i] + w[i];
        uint32_t t2 = (BUNDLE_ROR(a, 2) ^ BUNDLE_ROR(a, 13) ^ BUNDLE_ROR(a, 22))
                      + ((a & b) ^ (a & c) ^ (b & c));
        h = g, g = f, f = e, e = d + t1, d = c, c = b, b = a, a = t1 + t2;
    }
    uint32_t v[8] = {a, b, c, d, e, f, g, h};
    for (int i = 0; i < 8; i++)
        s->state[i] += v[i];
}

static void bundle_sha256_add(bundle_sha256 *s, const unsigned char *data, size_t n)
{
    s->length += n;
    while (s->used == 0 && n >= 64) {       /* whole blocks straight from the data */
        bundle_sha256_block(s, data);
        data += 64, n -= 64;
    }
    while (n > 0) {
        size_t take = 64 - s->used < n ? 64 - s->used : n;
        memcpy(s->block + s->used, data, take);
        s->used += take, data += take, n -= take;
        if (s->used == 64) {
            bundle_sha256_block(s, s->block);
            s->used = 0;
        }
    }
}

static void bundle_sha256_hex(bundle_sha256 *s, char hex[65])
{
    uint64_t bits = s->length * 8;
    unsigned char pad = 0x80, zero = 0, size[8];
    bundle_sha256_add(s, &pad, 1);
    while (s->used != 56)
        bundle_sha256_add(s, &zero, 1);
    for (int i = 0; i < 8; i++)
        size[i] = (unsigned char)(bits >> (56 - 8 * i));
    bundle_sha256_add(s, size, 8);
    for (int i = 0; i < 32; i++)
        snprintf(hex + 2 * i, 3, "%02x", (unsigned)(s->state[i / 4] >> (24 - 8 * (i % 4))) & 0xff);
}

/* 0 when the file at path has this size and hash; else -1 and why */
static int bundle_check_file(const char *path, const char *name, long long size,
                             const char *hash, char *why, size_t why_size)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        snprintf(why, why_size, "%s is missing or unreadable (%s)", name,
                 fd < 0 ? strerror(errno) : "not a regular file");
        if (fd >= 0)
            close(fd);
        return -1;
    }
    if ((long long)st.st_size != size) {
        close(fd);
        snprintf(why, why_size, "%s has %lld bytes, the build recorded %lld", name,
                 (long long)st.st_size, size);
        return -1;
    }
    bundle_sha256 s = {{0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c,
                        0x1f83d9ab, 0x5be0cd19}, 0, {0}, 0};
    static unsigned char buffer[1 << 16];
    ssize_t got;
    while ((got = read(fd, buffer, sizeof buffer)) > 0)
        bundle_sha256_add(&s, buffer, (size_t)got);
    close(fd);
    char hex[65];
    bundle_sha256_hex(&s, hex);
    if (got < 0 || strcmp(hex, hash) != 0) {
        snprintf(why, why_size, "%s has other contents than the build recorded (SHA-256 %.12s..., "
                 "recorded %.12s...)", name, hex, hash);
        return -1;
    }
    return 0;
}

static int bundle_check(const char *root, const char *list, const char *only, char *why,
                        size_t why_size)
{
    char path[4096], line[4608], name[4096], hash[65];
    snprintf(path, sizeof path, "%s/%s", root, list);
    FILE *file = fopen(path, "re");
    if (!file) {
        snprintf(why, why_size, "%s is missing (%s)", list, strerror(errno));
        return -1;
    }
    int result = 0, files = 0;
    while (result == 0 && fgets(line, sizeof line, file)) {
        long long size;
        if (sscanf(line, "%lld %64[0-9a-f] %4095[^\n]", &size, hash, name) != 3
                || strlen(hash) != 64 || size < 0 || strstr(name, "..")) {
            snprintf(why, why_size, "%s line %d is not \"<size> <sha-256> <path>\"", list,
                     files + 1);
            result = -1;
            break;
        }
        files++;
        if (only && strcmp(name, only) != 0)
            continue;
        snprintf(path, sizeof path, "%s/%s", root, name);
        result = bundle_check_file(path, name, size, hash, why, why_size);
    }
    fclose(file);
    if (result == 0 && files == 0) {
        snprintf(why, why_size, "%s lists no file", list);
        result = -1;
    }
    return result;
}

#endif
