// Whether this translation unit is built with AddressSanitizer, asked one way everywhere: GCC
// defines __SANITIZE_ADDRESS__, Clang 14 (the host-debug and fuzz compiler) answers only
// __has_feature(address_sanitizer). A bare `#if defined(__SANITIZE_ADDRESS__)` is silently false
// under Clang: heap poisoning off, the tests' malloc counters reading the wrong source.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define ZM_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ZM_ASAN 1
#endif
#endif
#ifndef ZM_ASAN
#define ZM_ASAN 0
#endif
