/* Built against an installed tessel by tests/install/run.sh: proves the
 * header, libraries, CMake package and pkg-config file work together. */
#include <tessel.h>
#include <stdio.h>
#include <string.h>

int main(void)
{
    tessel_cloud cloud;
    if (tessel_cloud_alloc(&cloud, 4, 0, 0) != TESSEL_OK)
        return 1;
    tessel_cloud_free(&cloud);
    if (strcmp(tessel_version(), TESSEL_VERSION_STRING) != 0)
        return 1;
    printf("tessel %s: %s\n", tessel_version(), tessel_status_str(TESSEL_OK));
    return 0;
}
