/* test_log.c: pf_log_printable, the escaping of peer-supplied strings before
 * they are logged (control characters, escape sequences, high bytes,
 * backslashes, truncation at an escape boundary). */
#include <string.h>

#include "base/log.h"
#include "check.h"

static void s_expect(const char *src, unsigned long cap, const char *want)
{
    char buf[256];
    memset(buf, 'Z', sizeof buf);
    pf_log_printable(buf, cap, src);
    CHECK(strcmp(buf, want) == 0, "cap %lu: got \"%s\", want \"%s\"", cap, buf, want);
    CHECK(strlen(buf) < cap, "cap %lu: %zu bytes", cap, strlen(buf));
}

int main(void)
{
    /* Plain text is kept as it is. */
    s_expect("render-07:1234", 64, "render-07:1234");
    s_expect("", 8, "");
    s_expect(NULL, 16, "(null)");
    /* An ANSI escape sequence, a forged second line, a bell, DEL. */
    s_expect("\x1b[2J\x1b[31mred", 64, "\\x1b[2J\\x1b[31mred");
    s_expect("ok\nerror: forged", 64, "ok\\x0aerror: forged");
    s_expect("a\rb\tc\x07\x7f", 64, "a\\x0db\\x09c\\x07\\x7f");
    /* High bytes (UTF-8 or not) are escaped too, and the backslash itself,
     * so an escape in the log cannot be faked. */
    s_expect("\xc3\xa9\xff", 64, "\\xc3\\xa9\\xff");
    s_expect("a\\x1b", 64, "a\\\\x1b");
    /* Truncation: the result fits cap, ends in "..." and never cuts an
     * escape in half. */
    s_expect("abcdefghij", 8, "abcd...");
    s_expect("abcdefg", 8, "abcdefg");
    s_expect("ab\x1b" "cdefgh", 9, "ab...");
    s_expect("ab\x1b" "cdefgh", 10, "ab\\x1b...");
    s_expect("abcdef", 4, "abc");
    s_expect("abcdef", 1, "");
    /* Every byte value: no control byte survives, the length is bounded. */
    char all[256], out[1100];
    for (int i = 1; i < 256; i++)
        all[i - 1] = (char)i;
    all[255] = '\0';
    pf_log_printable(out, sizeof out, all);
    for (const unsigned char *p = (const unsigned char *)out; *p; p++)
        CHECK(*p >= 0x20 && *p < 0x7f);
    CHECK(strstr(out, "...") == NULL);
    /* 94 printable bytes as they are, the backslash doubled, 31 + 129
     * others as \xHH. */
    CHECK(strlen(out) == 94 + 2 + 160 * 4, "%zu bytes", strlen(out));
    return pf_test_finish();
}
