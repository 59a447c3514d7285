/* keep_loaded.c - preloaded into every process of a sanitizer pass
 * (tests/CMakeLists.txt): dlclose does nothing, so that a library unloaded
 * before exit (the Vulkan loader unloads the driver in vkDestroyInstance)
 * is still mapped when LeakSanitizer names the modules of a leak's stack.
 * Without it a leak inside the driver shows as "<unknown module>", which no
 * suppression can name, and one through skyd's code loses its frames. */
int dlclose(void *handle);

int dlclose(void *handle)
{
	(void)handle;
	return 0;
}
