/* The environment switches (docs/api.md#environment-switches), read in one
 * place, once per system: each picks between code paths that give the same
 * bits, so tests can cover both sides of every choice on any machine. */
#include "core/core.h"

#include <stdlib.h>

/* The first character of the variable, or 0 when it is unset. */
static char first(const char *name)
{
    const char *v = getenv(name);
    return v ? v[0] : 0;
}

psys__switches psys__switches_from_env(void)
{
    psys__switches sw;
    sw.fused = first("PSYS_FUSED");
    sw.chain = first("PSYS_CHAIN");
    sw.spring_plain = first("PSYS_SPRING_PLAIN") == '1';
    sw.spring_order_off = first("PSYS_SPRING_ORDER") == '0';
    sw.state_order_off = first("PSYS_STATE_ORDER") == '0';
    sw.scan_plain = getenv("PSYS_SCAN_PLAIN") != NULL;
    sw.window_double = getenv("PSYS_WINDOW_DOUBLE") != NULL;
    sw.group_off = getenv("PSYS_GROUP_OFF") != NULL;
    sw.group8_off = getenv("PSYS_GROUP8_OFF") != NULL;
    return sw;
}
