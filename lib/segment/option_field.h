// One option of a segmentation stage by name: each stage declares its fields once (cut.h,
// merge.h, write.h), and the command line's `--param KEY=VALUE` and the layout merge model's
// record of the options it was trained with (layout_merge.h) read them from there.
#pragma once

namespace zm {

template <class Options>
struct OptionField {
  const char* name;
  double Options::*field;  // every option is a number in its unit (metres, m2, a ratio)
};

}  // namespace zm
