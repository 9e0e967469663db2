/* SPDX-License-Identifier: GPL-3.0-or-later */
/* CRC-32C, byte-wise with a 256-entry table built on first use (crc32c.h). */
#include "crc32c.h"

#include <pthread.h>

static uint32_t table[256];
static pthread_once_t once = PTHREAD_ONCE_INIT;

static void make_table(void)
{
    for (uint32_t i = 0; i < 256; i++) {
        uint32_t c = i;
        for (int k = 0; k < 8; k++)
            c = (c >> 1) ^ (0x82f63b78u & (0u - (c & 1u)));
        table[i] = c;
    }
}

uint32_t ftm_crc32c(uint32_t crc, const void *p, size_t n)
{
    pthread_once(&once, make_table);
    const uint8_t *b = p;
    crc = ~crc;
    while (n--)
        crc = (crc >> 8) ^ table[(crc ^ *b++) & 0xffu];
    return ~crc;
}
