/* SPDX-License-Identifier: GPL-3.0-or-later */
/* DDS Security for a transport: a participant's bundle (the directory that
 * deploy/ftm-security issue makes) checked with OpenSSL before Cyclone sees
 * it, and turned into the <Security> part of the Cyclone configuration.
 *
 * Cyclone's security plugins reject a bad bundle too, but only as a failed
 * dds_create_participant ("Error"), with the reason on standard error or in
 * its trace. What is cheap to check here is checked here, so that a missing
 * or unreadable file, a key that is not the certificate's, a certificate of
 * another CA or out of its validity, and documents not signed by the
 * permissions CA are reported with the file and the cause.
 *
 * A room has two CAs: the identity CA signs the participants' certificates,
 * the permissions CA the governance and the permissions. Cyclone DDS 0.10
 * verifies those documents as a chain (PKCS7_verify without PKCS7_NOINTERN,
 * CVE-2023-24011): a document signed by any certificate that chains to the
 * permissions CA passes. With one CA for both, every participant could sign
 * itself a server's or an instructor's permissions; with two, only the
 * permissions CA's own certificate chains to it. So a bundle whose two CAs
 * are one, or of the earlier one-CA layout (ca.pem), is refused, and the
 * documents are verified here with the permissions CA as the only signer,
 * trusting no certificate carried inside them. That guards our own
 * programs; a participant that skips this check is refused by the Cyclone
 * of the genuine ones (tests/net/net_secure.sh, mode session). */
#define _DEFAULT_SOURCE /* realpath */
#include "wire_internal.h"

#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/pkcs7.h>
#include <openssl/x509.h>
#include <openssl/x509_vfy.h>

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#ifndef FTM_DDS_SECURITY_LIBDIR
#define FTM_DDS_SECURITY_LIBDIR ""
#endif

/* The files of a bundle (docs/deploy.md, "Securing a session"). */
#define ID_CA_FILE "identity_ca.pem"
#define PERM_CA_FILE "permissions_ca.pem"
#define CERT_FILE "cert.pem"
#define KEY_FILE "key.pem"
#define GOVERNANCE_FILE "governance.p7s"
#define PERMISSIONS_FILE "permissions.p7s"
/* The one CA of a room made by ftm-security before it made two. */
#define ONE_CA_FILE "ca.pem"

/* How to make a room of two CAs, for messages. */
#define UPGRADE_HINT                                                                               \
    "make a room of two CAs from it, keeping each participant's name, role and id: "               \
    "'ftm-security upgrade ROOM NEW_ROOM' (ROOM: the directory with ca.key), then use "            \
    "NEW_ROOM/NAME"

typedef struct bundle {
    char dir[PATH_MAX];
    X509 *id_ca, *perm_ca, *cert;
    EVP_PKEY *key;
    X509_STORE *id_store;        /* the identity CA: verifies the certificate */
    X509_STORE *perm_store;      /* the permissions CA: verifies the documents */
    STACK_OF(X509) *perm_signer; /* the permissions CA: their only signer */
} bundle;

static void bundle_path(const bundle *b, const char *file, char *out, size_t cap)
{
    snprintf(out, cap, "%s/%s", b->dir, file);
}

/* The first OpenSSL error, for messages ("" if none). */
static const char *ossl_reason(void)
{
    static _Thread_local char buf[160];
    unsigned long e = ERR_peek_last_error();
    buf[0] = 0;
    if (e) {
        const char *r = ERR_reason_error_string(e);
        snprintf(buf, sizeof buf, ": %s", r ? r : "unknown OpenSSL error");
    }
    ERR_clear_error();
    return buf;
}

static int open_file(const bundle *b, const char *file, FILE **f, ftm_error *err)
{
    char path[PATH_MAX + 32];
    bundle_path(b, file, path, sizeof path);
    *f = fopen(path, "r");
    if (!*f)
        return ftm_error_set(err, FTM_EIO, "DDS Security: %s: %s", path, strerror(errno));
    return FTM_OK;
}

static int load_cert(const bundle *b, const char *file, X509 **out, ftm_error *err)
{
    FILE *f;
    int rc = open_file(b, file, &f, err);
    if (rc)
        return rc;
    *out = PEM_read_X509(f, NULL, NULL, NULL);
    fclose(f);
    if (!*out)
        return ftm_error_set(err, FTM_EPARSE, "DDS Security: %s/%s is not a PEM certificate%s", b->dir,
                        file, ossl_reason());
    return FTM_OK;
}

static int load_key(bundle *b, ftm_error *err)
{
    char path[PATH_MAX + 32];
    bundle_path(b, KEY_FILE, path, sizeof path);
    struct stat st;
    if (stat(path, &st) == 0 && (st.st_mode & 077))
        return ftm_error_set(err, FTM_EINVAL,
                        "DDS Security: the private key %s may be read by others (mode %04o): "
                        "chmod 600 it",
                        path, (unsigned)(st.st_mode & 07777));
    FILE *f;
    int rc = open_file(b, KEY_FILE, &f, err);
    if (rc)
        return rc;
    b->key = PEM_read_PrivateKey(f, NULL, NULL, NULL);
    fclose(f);
    if (!b->key)
        return ftm_error_set(err, FTM_EPARSE, "DDS Security: %s is not an unencrypted PEM private key%s",
                        path, ossl_reason());
    return FTM_OK;
}

/* What print wrote to a memory BIO, as text in out ("" if it failed). */
static void bio_text(BIO *m, int printed, char *out, size_t cap)
{
    out[0] = 0;
    if (m && printed > 0) {
        int n = BIO_read(m, out, (int)cap - 1);
        out[n > 0 ? n : 0] = 0;
    }
    BIO_free(m);
}

static void asn1_time_text(const ASN1_TIME *t, char *out, size_t cap)
{
    BIO *m = BIO_new(BIO_s_mem());
    bio_text(m, m ? ASN1_TIME_print(m, t) : 0, out, cap);
}

/* A certificate's subject as DDS Security writes it (RFC 2253). */
static void subject_text(X509 *c, char *out, size_t cap)
{
    BIO *m = BIO_new(BIO_s_mem());
    bio_text(m, m ? X509_NAME_print_ex(m, X509_get_subject_name(c), 0, XN_FLAG_RFC2253) : 0, out,
             cap);
}

/* Whether c is signed by the key of ca's certificate. */
static bool signed_by(X509 *c, X509 *ca)
{
    EVP_PKEY *k = X509_get0_pubkey(ca);
    const bool yes = k && X509_verify(c, k) == 1;
    ERR_clear_error();
    return yes;
}

/* A bundle of a room made with one CA for identities and permissions. */
static int check_not_one_ca(const bundle *b, ftm_error *err)
{
    char path[PATH_MAX + 32], one[PATH_MAX + 32];
    bundle_path(b, ID_CA_FILE, path, sizeof path);
    bundle_path(b, ONE_CA_FILE, one, sizeof one);
    struct stat st;
    if (stat(path, &st) == 0 || stat(one, &st) != 0)
        return FTM_OK;
    return ftm_error_set(err, FTM_EINVAL,
                    "DDS Security: %s is a bundle of a room with one CA (%s) for identities and "
                    "permissions, made by an earlier ftm-security: any participant of such a room "
                    "can sign itself a server's or an instructor's permissions (CVE-2023-24011), "
                    "so it is refused; " UPGRADE_HINT,
                    b->dir, ONE_CA_FILE);
}

/* The two CAs: two roots, neither the other, each within its validity
 * (the identity CA's is checked with the certificate). */
static int check_cas(const bundle *b, ftm_error *err)
{
    const char *d = b->dir;
    const char *same = X509_cmp(b->id_ca, b->perm_ca) == 0 ? "the same certificate"
                       : EVP_PKEY_eq(X509_get0_pubkey(b->id_ca), X509_get0_pubkey(b->perm_ca)) == 1
                           ? "of the same key"
                           : NULL;
    ERR_clear_error();
    if (same)
        return ftm_error_set(err, FTM_EINVAL,
                        "DDS Security: the identity CA %s/" ID_CA_FILE " and the permissions CA "
                        "%s/" PERM_CA_FILE " are %s: any participant could sign itself any "
                        "permissions (CVE-2023-24011); use a bundle of a room made by "
                        "'ftm-security init' (two CAs); for a room of one CA, " UPGRADE_HINT,
                        d, d, same);
    X509 *ca[2] = {b->id_ca, b->perm_ca};
    const char *file[2] = {ID_CA_FILE, PERM_CA_FILE};
    for (int i = 0; i < 2; i++) {
        const int self = X509_self_signed(ca[i], 1);
        ERR_clear_error();
        if (self != 1)
            return ftm_error_set(err, FTM_EINVAL,
                            "DDS Security: the CA %s/%s is not self-signed: FTM takes each CA of a "
                            "room as a root of its own (a chain between them could let a "
                            "participant's certificate sign permissions); 'ftm-security init' "
                            "makes them so",
                            d, file[i]);
    }
    char when[64];
    const ASN1_TIME *nb = X509_get0_notBefore(b->perm_ca), *na = X509_get0_notAfter(b->perm_ca);
    if (X509_cmp_current_time(na) <= 0) {
        asn1_time_text(na, when, sizeof when);
        return ftm_error_set(err, FTM_EINVAL,
                        "DDS Security: the permissions CA %s/" PERM_CA_FILE " expired on %s: "
                        "make a new room (ftm-security init)",
                        d, when);
    }
    if (X509_cmp_current_time(nb) >= 0) {
        asn1_time_text(nb, when, sizeof when);
        return ftm_error_set(err, FTM_EINVAL,
                        "DDS Security: the permissions CA %s/" PERM_CA_FILE " is not valid before "
                        "%s (is this machine's clock right?)",
                        d, when);
    }
    return FTM_OK;
}

/* The certificate against the identity CA: signature, validity, the key. */
static int check_cert(bundle *b, ftm_error *err)
{
    X509_STORE_CTX *ctx = X509_STORE_CTX_new();
    if (!ctx || !X509_STORE_CTX_init(ctx, b->id_store, b->cert, NULL)) {
        X509_STORE_CTX_free(ctx);
        return ftm_error_set(err, FTM_ENOMEM, "DDS Security: out of memory");
    }
    const int ok = X509_verify_cert(ctx);
    const int e = X509_STORE_CTX_get_error(ctx);
    X509 *bad = X509_STORE_CTX_get_current_cert(ctx);
    const bool is_ca = bad && X509_cmp(bad, b->id_ca) == 0;
    char when[64];
    X509_STORE_CTX_free(ctx);
    ERR_clear_error();
    if (ok != 1) {
        const char *which = is_ca ? ID_CA_FILE : CERT_FILE;
        switch (e) {
        case X509_V_ERR_CERT_HAS_EXPIRED:
        case X509_V_ERR_CERT_NOT_YET_VALID: {
            const bool expired = e == X509_V_ERR_CERT_HAS_EXPIRED;
            const X509 *c = is_ca ? b->id_ca : b->cert;
            asn1_time_text(expired ? X509_get0_notAfter(c) : X509_get0_notBefore(c), when,
                           sizeof when);
            const char *fix = !expired ? " (is this machine's clock right?)"
                              : is_ca  ? ": make a new room (ftm-security init)"
                                       : ": have a new one issued (deploy/ftm-security issue)";
            return ftm_error_set(err, FTM_EINVAL, "DDS Security: the certificate %s/%s %s %s%s", b->dir,
                            which, expired ? "expired on" : "is not valid before", when, fix);
        }
        case X509_V_ERR_UNABLE_TO_GET_ISSUER_CERT_LOCALLY:
        case X509_V_ERR_UNABLE_TO_GET_ISSUER_CERT:
        case X509_V_ERR_CERT_SIGNATURE_FAILURE:
            if (signed_by(b->cert, b->perm_ca))
                return ftm_error_set(err, FTM_EINVAL,
                                "DDS Security: the certificate %s/" CERT_FILE " is signed by the "
                                "permissions CA %s/" PERM_CA_FILE ", which signs documents only: "
                                "a participant's certificate comes from the identity CA "
                                "(ftm-security issue)",
                                b->dir, b->dir);
            return ftm_error_set(err, FTM_EINVAL,
                            "DDS Security: the certificate %s/" CERT_FILE " is not signed by the "
                            "identity CA in %s/" ID_CA_FILE " (a certificate of another room?)",
                            b->dir, b->dir);
        default:
            return ftm_error_set(err, FTM_EINVAL, "DDS Security: the certificate %s/%s: %s", b->dir,
                            which, X509_verify_cert_error_string(e));
        }
    }
    if (X509_check_private_key(b->cert, b->key) != 1) {
        ERR_clear_error();
        return ftm_error_set(err, FTM_EINVAL, "DDS Security: %s/%s is not the key of the certificate %s/%s",
                        b->dir, KEY_FILE, b->dir, CERT_FILE);
    }
    return FTM_OK;
}

/* Why a document failed to verify: who signed it, as far as it says. */
static int signed_fail(const bundle *b, const char *path, PKCS7 *p7, ftm_error *err)
{
    const char *d = b->dir;
    /* the permissions CA first, then whatever certificate the document carries */
    STACK_OF(X509) *who = PKCS7_get0_signers(p7, b->perm_signer, 0);
    X509 *s = who && sk_X509_num(who) == 1 ? sk_X509_value(who, 0) : NULL;
    char subject[256] = "";
    if (s)
        subject_text(s, subject, sizeof subject);
    int rc;
    if (!s)
        rc = ftm_error_set(err, FTM_EINVAL,
                      "DDS Security: %s is not signed by the permissions CA in %s/" PERM_CA_FILE
                      " (a document of another room?)",
                      path, d);
    else if (X509_cmp(s, b->perm_ca) == 0)
        rc = ftm_error_set(err, FTM_EINVAL,
                      "DDS Security: %s does not verify with the permissions CA in %s/" PERM_CA_FILE
                      ": it was changed after signing",
                      path, d);
    else if (X509_cmp(s, b->id_ca) == 0)
        rc = ftm_error_set(err, FTM_EINVAL,
                      "DDS Security: %s is signed by the identity CA %s/" ID_CA_FILE
                      ", which signs certificates only: documents are signed by the permissions CA "
                      "%s/" PERM_CA_FILE " (ftm-security init and issue)",
                      path, d, d);
    else if (signed_by(s, b->id_ca))
        rc = ftm_error_set(err, FTM_EINVAL,
                      "DDS Security: %s is signed by a participant's certificate ('%s'), not by "
                      "the permissions CA in %s/" PERM_CA_FILE ": forged (a participant signing "
                      "its own permissions, CVE-2023-24011)",
                      path, subject, d);
    else
        rc = ftm_error_set(err, FTM_EINVAL,
                      "DDS Security: %s is signed by '%s', not by the permissions CA in "
                      "%s/" PERM_CA_FILE " (a document of another room?)",
                      path, subject, d);
    sk_X509_free(who);
    ERR_clear_error();
    return rc;
}

/* A document signed by the permissions CA's own certificate (S/MIME,
 * openssl smime -sign -signer permissions_ca.pem); its content (malloc'ed,
 * NUL-terminated) to *text if text is not NULL. PKCS7_NOINTERN: the signer
 * is looked for among b->perm_signer only, never among the certificates the
 * document carries, so no certificate that chains to the CA will do. */
static int check_signed(const bundle *b, const char *file, char **text, ftm_error *err)
{
    char path[PATH_MAX + 32];
    bundle_path(b, file, path, sizeof path);
    FILE *f;
    int rc = open_file(b, file, &f, err);
    if (rc)
        return rc;
    fclose(f);
    BIO *in = BIO_new_file(path, "r"), *content = NULL, *out = BIO_new(BIO_s_mem());
    PKCS7 *p7 = in ? SMIME_read_PKCS7(in, &content) : NULL;
    if (!p7) {
        rc = ftm_error_set(err, FTM_EPARSE, "DDS Security: %s is not an S/MIME signed document%s", path,
                      ossl_reason());
    } else if (!out || !PKCS7_type_is_signed(p7)) {
        rc = ftm_error_set(err, FTM_EPARSE, "DDS Security: %s is not a signed document", path);
    } else if (PKCS7_verify(p7, b->perm_signer, b->perm_store, content, out,
                            PKCS7_TEXT | PKCS7_NOINTERN) != 1) {
        rc = signed_fail(b, path, p7, err);
    } else if (text) {
        char *data = NULL;
        long n = BIO_get_mem_data(out, &data);
        *text = malloc((size_t)(n > 0 ? n : 0) + 1);
        if (!*text) {
            rc = ftm_error_set(err, FTM_ENOMEM, "DDS Security: out of memory");
        } else {
            if (n > 0)
                memcpy(*text, data, (size_t)n);
            (*text)[n > 0 ? n : 0] = 0;
        }
    }
    ERR_clear_error();
    PKCS7_free(p7);
    BIO_free(content);
    BIO_free(in);
    BIO_free(out);
    return rc;
}

/* The permissions must have a grant for the certificate's subject (written
 * as DDS Security compares it, RFC 2253). */
static int check_subject(const bundle *b, const char *permissions, ftm_error *err)
{
    char subject[512];
    subject_text(b->cert, subject, sizeof subject);
    static const char open_tag[] = "<subject_name>", close_tag[] = "</subject_name>";
    for (const char *p = strstr(permissions, open_tag); p; p = strstr(p, open_tag)) {
        p += sizeof open_tag - 1;
        const char *q = strstr(p, close_tag);
        if (!q)
            break;
        while (p < q && (*p == ' ' || *p == '\n' || *p == '\t' || *p == '\r'))
            p++;
        size_t n = (size_t)(q - p);
        while (n && (p[n - 1] == ' ' || p[n - 1] == '\n' || p[n - 1] == '\t' || p[n - 1] == '\r'))
            n--;
        if (n == strlen(subject) && strncmp(p, subject, n) == 0)
            return FTM_OK;
    }
    return ftm_error_set(err, FTM_EINVAL,
                    "DDS Security: the permissions %s/%s have no grant for '%s', the subject of "
                    "%s/%s (documents of two participants mixed up?)",
                    b->dir, PERMISSIONS_FILE, subject, b->dir, CERT_FILE);
}

static void bundle_free(bundle *b)
{
    X509_free(b->id_ca);
    X509_free(b->perm_ca);
    X509_free(b->cert);
    EVP_PKEY_free(b->key);
    X509_STORE_free(b->id_store);
    X509_STORE_free(b->perm_store);
    sk_X509_free(b->perm_signer);
}

/* A store holding ca alone. */
static X509_STORE *store_of(X509 *ca)
{
    X509_STORE *s = X509_STORE_new();
    if (s && X509_STORE_add_cert(s, ca) != 1) {
        X509_STORE_free(s);
        s = NULL;
    }
    return s;
}

static int check_bundle(bundle *b, ftm_error *err)
{
    int rc = check_not_one_ca(b, err);
    if (!rc)
        rc = load_cert(b, ID_CA_FILE, &b->id_ca, err);
    if (!rc)
        rc = load_cert(b, PERM_CA_FILE, &b->perm_ca, err);
    if (!rc)
        rc = load_cert(b, CERT_FILE, &b->cert, err);
    if (!rc)
        rc = load_key(b, err);
    if (rc)
        return rc;
    b->id_store = store_of(b->id_ca);
    b->perm_store = store_of(b->perm_ca);
    b->perm_signer = sk_X509_new_null();
    if (!b->id_store || !b->perm_store || !b->perm_signer ||
        !sk_X509_push(b->perm_signer, b->perm_ca))
        return ftm_error_set(err, FTM_ENOMEM, "DDS Security: out of memory");
    rc = check_cas(b, err);
    if (!rc)
        rc = check_cert(b, err);
    if (!rc)
        rc = check_signed(b, GOVERNANCE_FILE, NULL, err);
    char *permissions = NULL;
    if (!rc)
        rc = check_signed(b, PERMISSIONS_FILE, &permissions, err);
    if (!rc)
        rc = check_subject(b, permissions, err);
    free(permissions);
    return rc;
}

bool wire_partition_identity(const char *name, ftm_wire_role *role, uint32_t *id)
{
    const size_t np = strlen(FTM_WIRE_PARTITION_PREFIX);
    if (strncmp(name, FTM_WIRE_PARTITION_PREFIX, np) != 0)
        return false;
    name += np;
    for (int r = FTM_WIRE_ROLE_SERVER; r <= FTM_WIRE_ROLE_OBSERVER; r++) {
        const char *rn = ftm_wire_role_name((ftm_wire_role)r);
        const size_t n = strlen(rn);
        if (strncmp(name, rn, n) != 0 || name[n] != '.')
            continue;
        const char *d = name + n + 1;
        char *end = NULL;
        errno = 0;
        const unsigned long v = strtoul(d, &end, 10);
        if (*d < '1' || *d > '9' || *end || errno || v > UINT32_MAX)
            return false;
        *role = (ftm_wire_role)r;
        *id = (uint32_t)v;
        return true;
    }
    return false;
}

/* The role the bundle was issued for (its file "role"): the partition its
 * writers publish in names it. */
static int read_role(const bundle *b, ftm_wire_role *role, ftm_error *err)
{
    char path[PATH_MAX + 32];
    bundle_path(b, "role", path, sizeof path);
    FILE *f = fopen(path, "r");
    if (!f)
        return ftm_error_set(err, FTM_EIO, "DDS Security: %s: %s (a bundle of deploy/ftm-security issue "
                        "names its role there)", path, strerror(errno));
    char buf[32] = "";
    const int n = fscanf(f, "%31s", buf);
    fclose(f);
    for (int r = FTM_WIRE_ROLE_SERVER; n == 1 && r <= FTM_WIRE_ROLE_OBSERVER; r++)
        if (strcmp(buf, ftm_wire_role_name((ftm_wire_role)r)) == 0) {
            *role = (ftm_wire_role)r;
            return FTM_OK;
        }
    return ftm_error_set(err, FTM_EPARSE, "DDS Security: %s: not server, trainee, instructor or observer",
                    path);
}

/* The participant id the bundle was issued for (its file "id", written by
 * deploy/ftm-security issue --id) must be the one this transport uses: a
 * mix-up caught at start (not a defence: a hostile program need not check). */
static int check_id(const bundle *b, uint32_t id, ftm_error *err)
{
    char path[PATH_MAX + 32];
    bundle_path(b, "id", path, sizeof path);
    FILE *f = fopen(path, "r");
    if (!f)
        return FTM_OK; /* issued without --id */
    unsigned long want = 0;
    const int n = fscanf(f, "%lu", &want);
    fclose(f);
    if (n != 1 || want == 0 || want > UINT32_MAX)
        return ftm_error_set(err, FTM_EPARSE, "DDS Security: %s: not a participant id", path);
    if (want != id)
        return ftm_error_set(err, FTM_EINVAL,
                        "DDS Security: the identity in %s was issued for participant id %lu, "
                        "not %u (--id %lu)",
                        b->dir, want, id, want);
    return FTM_OK;
}

int wire_security_config(const char *dir, uint32_t id, char **xml, wire_security *out,
                         ftm_error *err)
{
    *xml = NULL;
    if (!FTM_DDS_SECURITY_LIBDIR[0])
        return ftm_error_set(err, FTM_EINVAL,
                        "DDS Security: this build found no Cyclone DDS security plugins "
                        "(libdds_security_auth.so, Debian package libddsc0debian)");
    bundle b;
    memset(&b, 0, sizeof b);
    struct stat st;
    if (stat(dir, &st) != 0)
        return ftm_error_set(err, FTM_EIO, "DDS Security: %s: %s", dir, strerror(errno));
    if (!S_ISDIR(st.st_mode))
        return ftm_error_set(err, FTM_EINVAL,
                        "DDS Security: %s is not a directory (give the participant's directory "
                        "made by deploy/ftm-security issue)",
                        dir);
    if (!realpath(dir, b.dir))
        return ftm_error_set(err, FTM_EIO, "DDS Security: %s: %s", dir, strerror(errno));
    /* Cyclone splits its configuration at commas; XML text needs none of < & " */
    if (strpbrk(b.dir, ",<>&\""))
        return ftm_error_set(err, FTM_EINVAL,
                        "DDS Security: the path %s has a character Cyclone DDS cannot take in a "
                        "configuration (one of , < > & \")",
                        b.dir);
    int rc = check_id(&b, id, err);
    if (!rc)
        rc = read_role(&b, &out->role, err);
    if (!rc)
        rc = check_bundle(&b, err);
    bundle_free(&b);
    if (rc)
        return rc;
    snprintf(out->permissions, sizeof out->permissions, "%s/%s", b.dir, PERMISSIONS_FILE);
    snprintf(out->partition, sizeof out->partition, "%s%s.%u", FTM_WIRE_PARTITION_PREFIX,
             ftm_wire_role_name(out->role), id);
    const char *d = b.dir, *lib = FTM_DDS_SECURITY_LIBDIR;
    const char *fmt =
        "<CycloneDDS><Domain Id=\"any\"><Security>"
        "<Authentication>"
        "<Library path=\"%s/libdds_security_auth.so\" initFunction=\"init_authentication\" "
        "finalizeFunction=\"finalize_authentication\"/>"
        "<IdentityCA>file:%s/" ID_CA_FILE "</IdentityCA>"
        "<IdentityCertificate>file:%s/" CERT_FILE "</IdentityCertificate>"
        "<PrivateKey>file:%s/" KEY_FILE "</PrivateKey>"
        "</Authentication>"
        "<AccessControl>"
        "<Library path=\"%s/libdds_security_ac.so\" initFunction=\"init_access_control\" "
        "finalizeFunction=\"finalize_access_control\"/>"
        "<PermissionsCA>file:%s/" PERM_CA_FILE "</PermissionsCA>"
        "<Governance>file:%s/" GOVERNANCE_FILE "</Governance>"
        "<Permissions>file:%s/" PERMISSIONS_FILE "</Permissions>"
        "</AccessControl>"
        "<Cryptographic>"
        "<Library path=\"%s/libdds_security_crypto.so\" initFunction=\"init_crypto\" "
        "finalizeFunction=\"finalize_crypto\"/>"
        "</Cryptographic>"
        "</Security></Domain></CycloneDDS>";
    int n = snprintf(NULL, 0, fmt, lib, d, d, d, lib, d, d, d, lib);
    *xml = n > 0 ? malloc((size_t)n + 1) : NULL;
    if (!*xml)
        return ftm_error_set(err, FTM_ENOMEM, "DDS Security: out of memory");
    snprintf(*xml, (size_t)n + 1, fmt, lib, d, d, d, lib, d, d, d, lib);
    return FTM_OK;
}
