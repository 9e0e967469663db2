/* SPDX-License-Identifier: GPL-3.0-or-later */
/* CRC-32C (Castagnoli, reflected polynomial 0x82f63b78), the checksum of
 * session recordings (record.h): the SSE4.2 crc32 instruction where the CPU
 * has it, else table-driven, one byte per step. */
#ifndef FTM_SERVER_CRC32C_H
#define FTM_SERVER_CRC32C_H

#include <stddef.h>
#include <stdint.h>

/* The CRC-32C of n bytes at p, continuing from crc (0 to start):
 * ftm_crc32c(0, "123456789", 9) == 0xe3069283. */
uint32_t ftm_crc32c(uint32_t crc, const void *p, size_t n);
/* The same, always with the table (tests: both ways give the same). */
uint32_t ftm_crc32c_table(uint32_t crc, const void *p, size_t n);

#endif
